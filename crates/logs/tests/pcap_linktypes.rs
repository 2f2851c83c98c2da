//! pcap and pcapng link types: SocketCAN (227) and Wireshark's exported PDUs (252) are read;
//! any other link type is an error naming it, never an empty log.

use std::io::Cursor;

use buslab_logs::{LogReader, Message, Problem, ReadError, Record, pcap, pcapng};

const LINKTYPE_ETHERNET: u16 = 1;
const LINKTYPE_CAN_SOCKETCAN: u16 = 227;
const LINKTYPE_WIRESHARK_UPPER_PDU: u16 = 252;

/// The 16-byte LINKTYPE_CAN_SOCKETCAN record of `frame`'s ID word, length and data.
fn socketcan(can_id: u32, data: &[u8]) -> Vec<u8> {
    let mut out = can_id.to_be_bytes().to_vec();
    out.extend([data.len() as u8, 0, 0, 0]);
    out.extend(data);
    out.resize(16, 0);
    out
}

/// A 72-byte CAN FD record of ID 0x321 with BRS and 12 bytes, without FDF.
fn fd_record() -> Vec<u8> {
    let mut out = 0x321u32.to_be_bytes().to_vec();
    out.extend([12, 0x01, 0, 0]);
    out.extend(0..12u8);
    out.resize(72, 0);
    out
}

/// An exported PDU: the tags (type, value), the end tag, then the payload.
fn exported(tags: &[(u16, &[u8])], payload: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    for (tag, value) in tags {
        out.extend(tag.to_be_bytes());
        out.extend((value.len() as u16).to_be_bytes());
        out.extend(*value);
    }
    out.extend([0, 0, 0, 0]);
    out.extend(payload);
    out
}

/// As Wireshark's `text2pcap -P can-bigendian` writes a SocketCAN frame.
fn can_pdu(can_id: u32, data: &[u8]) -> Vec<u8> {
    exported(&[(12, b"can-bigendian")], &socketcan(can_id, data))
}

fn pcap_file(linktype: u16, packets: &[Vec<u8>]) -> Vec<u8> {
    let mut out = 0xA1B2_C3D4u32.to_le_bytes().to_vec();
    out.extend(2u16.to_le_bytes());
    out.extend(4u16.to_le_bytes());
    out.extend([0; 8]);
    out.extend(65_535u32.to_le_bytes());
    out.extend(u32::from(linktype).to_le_bytes());
    for (i, p) in packets.iter().enumerate() {
        out.extend((1_700_000_000 + i as u32).to_le_bytes());
        out.extend(0u32.to_le_bytes());
        out.extend((p.len() as u32).to_le_bytes());
        out.extend((p.len() as u32).to_le_bytes());
        out.extend(p);
    }
    out
}

fn block(kind: u32, body: &[u8]) -> Vec<u8> {
    let mut body = body.to_vec();
    body.resize(body.len().next_multiple_of(4), 0);
    let len = (12 + body.len()) as u32;
    let mut out = kind.to_le_bytes().to_vec();
    out.extend(len.to_le_bytes());
    out.extend(body);
    out.extend(len.to_le_bytes());
    out
}

/// A pcapng section with one interface per link type and packets (interface, bytes).
fn pcapng_file(linktypes: &[u16], packets: &[(u32, Vec<u8>)]) -> Vec<u8> {
    let mut shb = 0x1A2B_3C4Du32.to_le_bytes().to_vec();
    shb.extend([1, 0, 0, 0]);
    shb.extend((-1i64).to_le_bytes());
    let mut out = block(0x0A0D_0D0A, &shb);
    for l in linktypes {
        let mut idb = l.to_le_bytes().to_vec();
        idb.extend([0, 0, 0, 0, 0, 0]);
        out.extend(block(1, &idb));
    }
    for (i, (iface, p)) in packets.iter().enumerate() {
        let mut epb = iface.to_le_bytes().to_vec();
        let micros = 1_700_000_000_000_000u64 + i as u64;
        epb.extend(((micros >> 32) as u32).to_le_bytes());
        epb.extend((micros as u32).to_le_bytes());
        epb.extend((p.len() as u32).to_le_bytes());
        epb.extend((p.len() as u32).to_le_bytes());
        epb.extend(p);
        out.extend(block(6, &epb));
    }
    out
}

fn read_all(mut reader: impl LogReader, max: usize) -> Vec<Result<Message, ReadError>> {
    let mut out = Vec::new();
    for _ in 0..max {
        let mut e = Message::default();
        match reader.read_into(&mut e) {
            Ok(true) => out.push(Ok(e)),
            Ok(false) => return out,
            Err(err) => {
                let fatal = err.is_fatal();
                out.push(Err(err));
                if fatal {
                    return out;
                }
            }
        }
    }
    panic!("the reader does not end");
}

fn records(results: &[Result<Message, ReadError>]) -> Vec<String> {
    results
        .iter()
        .map(|r| match r {
            Ok(e) => buslab_logs::candump::format_line(e, false)
                .split(' ')
                .nth(2)
                .unwrap()
                .to_string(),
            Err(e) => format!("error: {e}"),
        })
        .collect()
}

fn upper_pdus() -> Vec<Vec<u8>> {
    vec![
        can_pdu(0x123, &[0x11, 0x22]),
        can_pdu(0x8000_0000 | 0x1234_5678, &[0xDE, 0xAD]),
        can_pdu(0x2000_0088, &[0, 0, 0x02, 0x0A, 0, 0, 0x01, 0x02]),
        // The deprecated link-type tag saying 227, strings padded with NULs, other tags.
        exported(
            &[(10, &[0, 0, 0, 8]), (11, &[0, 0, 0, 227])],
            &socketcan(0x7FF, &[]),
        ),
        exported(
            &[(12, b"can-bigendian\0\0\0"), (33, b"CAN")],
            &socketcan(0x4000_0001, &[]),
        ),
    ]
}

const UPPER_RECORDS: [&str; 5] = [
    "123#1122",
    "12345678#DEAD",
    "20000088#0000020A00000102",
    "7FF#",
    "001#R",
];

/// Issue 25: a Wireshark pcapng of exported PDUs (link type 252) read as 0 entries, exit 0.
#[test]
fn exported_socketcan_pdus_are_read_from_pcap_and_pcapng() {
    let pcap = pcap_file(LINKTYPE_WIRESHARK_UPPER_PDU, &upper_pdus());
    let got = read_all(pcap::Reader::new(Cursor::new(pcap)), 20);
    assert_eq!(records(&got), UPPER_RECORDS);
    let packets: Vec<(u32, Vec<u8>)> = upper_pdus().into_iter().map(|p| (0, p)).collect();
    let pcapng = pcapng_file(&[LINKTYPE_WIRESHARK_UPPER_PDU], &packets);
    let got = read_all(pcapng::Reader::new(Cursor::new(pcapng)), 20);
    assert_eq!(records(&got), UPPER_RECORDS);
}

#[test]
fn exported_pdus_of_other_dissectors_are_refused_naming_them() {
    let pdus = vec![
        exported(&[(12, b"sip")], b"INVITE sip:x"),
        exported(&[(12, b"can-hostendian")], &socketcan(0x0123_0000, &[])),
        exported(&[(12, b"canfd")], &fd_record()),
        exported(&[(11, &[0, 0, 0, 1])], &[0; 20]),
        exported(&[(20, &[127, 0, 0, 1])], &[0; 16]),
        // Tags that run past the packet, a packet without the end tag.
        vec![0, 12, 0, 40, b'c', b'a', b'n'],
        vec![0, 12],
        can_pdu(0x123, &[0x11]),
    ];
    let got = read_all(
        pcap::Reader::new(Cursor::new(pcap_file(LINKTYPE_WIRESHARK_UPPER_PDU, &pdus))),
        20,
    );
    let text = records(&got);
    assert!(
        text[0].contains("dissector sip") && text[0].contains("can-bigendian"),
        "{text:?}"
    );
    assert!(text[1].contains("dissector can-hostendian"), "{text:?}");
    // Wireshark's CAN FD dissector: a CAN FD record (here without FDF; the dissector says FD).
    assert_eq!(text[2], "321##1000102030405060708090A0B");
    assert!(text[3].contains("link type 1 (Ethernet)"), "{text:?}");
    assert!(text[4].contains("naming its dissector"), "{text:?}");
    assert!(text[5].contains("tag 12 of 40 bytes"), "{text:?}");
    assert!(text[6].contains("ending with tag 0"), "{text:?}");
    assert_eq!(text[7], "123#11");
    assert!(
        got[..7]
            .iter()
            .enumerate()
            .all(|(i, r)| i == 2 || r.as_ref().is_err_and(|e| !e.is_fatal()))
    );
}

/// A capture that holds no CAN is an error naming its link type, not an empty log.
#[test]
fn other_link_types_are_errors_naming_them() {
    let ethernet = vec![vec![0u8; 60]; 3];
    let got = read_all(
        pcap::Reader::new(Cursor::new(pcap_file(LINKTYPE_ETHERNET, &ethernet))),
        20,
    );
    assert_eq!(got.len(), 1);
    let err = got[0].as_ref().unwrap_err();
    assert!(err.is_fatal());
    assert!(
        matches!(err.problem(), Problem::LinkType { linktype: 1, .. }),
        "{err}"
    );
    assert!(
        err.to_string()
            .contains("link type 1 (Ethernet) is not CAN"),
        "{err}"
    );

    // pcapng: the first packet of a non-CAN interface is a bad record naming its link type;
    // stepped over, that interface's later packets are left out and the CAN ones read.
    let packets = vec![
        (0, vec![0u8; 60]),
        (1, socketcan(0x123, &[1])),
        (0, vec![0u8; 60]),
        (2, vec![0u8; 40]),
        (1, socketcan(0x124, &[2])),
    ];
    let file = pcapng_file(&[LINKTYPE_ETHERNET, LINKTYPE_CAN_SOCKETCAN, 101], &packets);
    let got = read_all(pcapng::Reader::new(Cursor::new(file)), 20);
    let text = records(&got);
    assert_eq!(text.len(), 4, "{text:?}");
    assert!(
        text[0].contains("interface 0 (can0): link type 1 (Ethernet) is not CAN"),
        "{text:?}"
    );
    assert_eq!(text[1], "123#01");
    assert!(
        text[2].contains("interface 2 (can2): link type 101 (raw IP)"),
        "{text:?}"
    );
    assert_eq!(text[3], "124#02");
    assert!(!got[0].as_ref().unwrap_err().is_fatal());
    // Only other link types: the first read is an error, so no tool ends with "0 entries".
    let only = pcapng_file(&[LINKTYPE_ETHERNET], &vec![(0, vec![0u8; 60]); 4]);
    let got = read_all(pcapng::Reader::new(Cursor::new(only)), 20);
    assert_eq!(got.len(), 1);
    assert!(matches!(
        got[0].as_ref().unwrap_err().problem(),
        Problem::Interface { .. }
    ));
}

#[test]
fn error_frames_keep_their_bytes_and_length_in_pcap_and_pcapng() {
    let entries: Vec<Message> = [
        "20000088#0000020A00000102",
        "20000080#0000040200000001",
        "20000004#0004",
        "20000040#",
    ]
    .iter()
    .enumerate()
    .map(|(i, text)| {
        buslab_logs::candump::parse_line(&format!("(1700000000.00000{i}) can0 {text}")).unwrap()
    })
    .collect();
    let mut w = pcapng::Writer::new(Vec::new()).unwrap();
    let mut p = pcap::Writer::new(Vec::new()).unwrap();
    for e in &entries {
        w.write(e).unwrap();
        p.write(e).unwrap();
    }
    for bytes in [w.finish().unwrap(), p.finish().unwrap()] {
        let pcapng = bytes.starts_with(&0x0A0D_0D0Au32.to_le_bytes());
        let got: Vec<Record> = if pcapng {
            read_all(pcapng::Reader::new(Cursor::new(bytes)), 20)
        } else {
            read_all(pcap::Reader::new(Cursor::new(bytes)), 20)
        }
        .into_iter()
        .map(|r| r.unwrap().record)
        .collect();
        let want: Vec<Record> = entries.iter().map(|e| e.record.clone()).collect();
        assert_eq!(got, want);
    }
}
