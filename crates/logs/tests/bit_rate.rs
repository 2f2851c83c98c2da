//! The bit rate a log gives (`LogReader::bit_rate`), which `buslab log info` computes the load
//! at: a TRC header's connection table, the frame lengths CANoe writes in ASC, nothing in the
//! formats that do not carry it.

use std::io::Cursor;

use buslab_logs::{BitRateSource, Format, LogBitRate, LogReader, Message, reader};

/// Reads `text` as `format` to its end and gives the reader.
fn read_all(text: &str, format: Format) -> Box<dyn LogReader + Send> {
    let mut r = reader(Cursor::new(text.as_bytes().to_vec()), format).unwrap();
    let mut e = Message::default();
    let mut entries = 0;
    while r.read_into(&mut e).unwrap() {
        entries += 1;
    }
    assert!(entries > 0, "no entry in\n{text}");
    r
}

fn rate(bits_per_s: u32, source: BitRateSource) -> Option<LogBitRate> {
    Some(LogBitRate { bits_per_s, source })
}

#[test]
fn asc_frame_lengths_give_each_channels_rate() {
    // CANoe's lines (python-can's test data has them): 6F9#050C000000000000 is 120 bits on the
    // wire, 240015 ns at 500 kbit/s; 180#6A00000000000000 is 122 bits, 976 µs at 125 kbit/s.
    let text = "base hex  timestamps absolute\nBegin Triggerblock\n\
        \x20 17.876708 1  6F9             Rx   d 8 05 0C 00 00 00 00 00 00  Length = 240015 BitCount = 124 ID = 1785\n\
        \x20 17.976708 2  180             Tx   d 8 6A 00 00 00 00 00 00 00  Length = 976000 BitCount = 125 ID = 384\n\
        \x20 18.000000 3  180             Tx   d 8 6A 00 00 00 00 00 00 00  Length = 0 BitCount = 0 ID = 384\n\
        \x20 18.100000 4  180             Rx   d 8 6A 00 00 00 00 00 00 00\n\
        End TriggerBlock\n";
    let r = read_all(text, Format::Asc);
    assert_eq!(
        r.bit_rate("can0"),
        rate(500_000, BitRateSource::FrameLengths)
    );
    assert_eq!(
        r.bit_rate("can1"),
        rate(125_000, BitRateSource::FrameLengths)
    );
    // Not measured (Length = 0), or no Length at all.
    assert_eq!(r.bit_rate("can2"), None);
    assert_eq!(r.bit_rate("can3"), None);
    assert_eq!(r.bit_rate("vcan0"), None);
}

#[test]
fn a_trc_connection_table_gives_each_bus_its_rate() {
    // PCAN-View's 1.3 header: a table of buses with their bit rates.
    let text = ";$FILEVERSION=1.3\r\n;$STARTTIME=40023.5245451516\r\n\
        ;-------------------------------------------------------------------------------\r\n\
        ;   Bus  Name         Connection             Protocol  Bit rate\r\n\
        ;   1    Connection1  TestNet@pcan_usb       CAN       125 kBit/s\r\n\
        ;   2    Connection2  Internal@pcan_usb      CAN       1 MBit/s\r\n\
        ;-------------------------------------------------------------------------------\r\n\
        \x20    1)      1059.900 1  Rx        0300 -  7    00 00 00 00 04 00 00\r\n\
        \x20    2)      1283.231 2  Rx        0300 -  7    00 00 00 00 04 00 00\r\n";
    let r = read_all(text, Format::Trc21);
    assert_eq!(r.bit_rate("can0"), rate(125_000, BitRateSource::Header));
    assert_eq!(r.bit_rate("can1"), rate(1_000_000, BitRateSource::Header));
    assert_eq!(r.bit_rate("can2"), None);

    // 2.0: one connection, no bus column; a CAN FD connection's nominal rate.
    let text = ";$FILEVERSION=2.0\r\n;$STARTTIME=42209.4075997106\r\n;$COLUMNS=N,O,T,I,d,l,D\r\n\
        ;   Connection                 Bit rate\r\n\
        ;   PCANLight_USB_16@pcan_usb  Nominal 500 kBit/s, Data 2 Mbit/s\r\n\
        ;-------------------------------------------------------------------------------\r\n\
        \x20     1      1059.900 DT     0300 Rx 7  00 00 00 00 04 00 00\r\n";
    let r = read_all(text, Format::Trc21);
    assert_eq!(r.bit_rate("can0"), rate(500_000, BitRateSource::Header));

    // python-can's converted files say N/A.
    let text = ";$FILEVERSION=2.0\r\n;$COLUMNS=N,O,T,I,d,l,D\r\n\
        ;   Connection                 Bit rate\r\n;   N/A                        N/A\r\n\
        ;-------------------------------------------------------------------------------\r\n\
        \x20     1      1059.900 DT     0300 Rx 7  00 00 00 00 04 00 00\r\n";
    assert_eq!(read_all(text, Format::Trc21).bit_rate("can0"), None);
}

#[test]
fn formats_without_a_bit_rate_say_none() {
    let r = read_all("(1.000000) can0 123#1122\n", Format::Candump);
    assert_eq!(r.bit_rate("can0"), None);
}

#[test]
fn garbage_where_a_rate_or_a_length_goes_gives_none() {
    let text = ";$FILEVERSION=1.3\r\n\
        ;   Bus  Name  Connection  Protocol  Bit rate\r\n\
        ;   1    a     b           CAN       99999999999999999999 MBit/s\r\n\
        ;   x    a     b           CAN       125 kBit/s\r\n\
        ;   2    a     b           CAN       NaN kBit/s\r\n\
        ;---\r\n\
        \x20    1)      1059.900 1  Rx        0300 -  1    00\r\n";
    let r = read_all(text, Format::Trc21);
    assert_eq!(r.bit_rate("can0"), None);
    assert_eq!(r.bit_rate("can1"), None);
    let text = "base hex  timestamps absolute\nBegin Triggerblock\n\
        \x20  1.000000 1  123  Rx   d 1 00  Length = 99999999999999999999999 BitCount = 1\n\
        \x20  1.100000 1  123  Rx   d 1 00  Length = 7 BitCount = 1\n\
        \x20  1.200000 1  123  Rx   d 1 00  Length = -5\n\
        End TriggerBlock\n";
    assert_eq!(read_all(text, Format::Asc).bit_rate("can0"), None);
}
