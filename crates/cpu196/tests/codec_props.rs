//! decode(encode(m)) == m for every message; garbage never panics and the stream recovers.

use buslab_cpu196::codes::{Alert, MsgCode};
use buslab_cpu196::message::*;
use buslab_cpu196::{Decoder, Event};
use buslab_device::Nanos;
use proptest::prelude::*;

fn bytes<const N: usize>() -> impl Strategy<Value = Box<[u8; N]>> {
    proptest::collection::vec(any::<u8>(), N).prop_map(|v| {
        let mut b = Box::new([0u8; N]);
        b.copy_from_slice(&v);
        b
    })
}

fn arr8() -> impl Strategy<Value = [u8; 8]> {
    any::<[u8; 8]>()
}

fn short(max: usize) -> impl Strategy<Value = Vec<u8>> {
    proptest::collection::vec(any::<u8>(), 0..=max)
}

fn thread() -> impl Strategy<Value = Thread> {
    let fmt = prop_oneof![
        Just(DisplayFormat::Text),
        Just(DisplayFormat::Hex8),
        Just(DisplayFormat::Hex16),
        Just(DisplayFormat::Unsigned8),
        Just(DisplayFormat::Unsigned16),
        Just(DisplayFormat::Signed8),
        Just(DisplayFormat::Signed16),
    ];
    prop_oneof![
        (fmt, any::<bool>(), short(255)).prop_map(|(format, newline, mut data)| {
            if format.is_word() {
                data.extend(data.clone());
            }
            Thread::Display {
                format,
                newline,
                data,
            }
        }),
        (any::<bool>(), short(40), any::<u8>()).prop_map(|(r, name, file)| Thread::Open {
            mode: if r { FileMode::Read } else { FileMode::Write },
            name,
            file
        }),
        any::<u8>().prop_map(|file| Thread::Close { file }),
        (any::<u8>(), any::<u8>()).prop_map(|(len, file)| Thread::ReadRequest { len, file }),
        (short(255), any::<u8>()).prop_map(|(data, file)| Thread::Write { data, file }),
        (short(255), any::<u8>()).prop_map(|(data, file)| Thread::ReadData { data, file }),
    ]
}

fn format() -> impl Strategy<Value = Format> {
    prop_oneof![
        arr8().prop_map(|nsc| Format::ReadPicKernel { nsc }),
        bytes().prop_map(Format::PicKernel),
        (arr8(), bytes()).prop_map(|(nsc, data)| Format::WritePicKernel { nsc, data }),
        (arr8(), arr8()).prop_map(|(nsc, new)| Format::NewSerial { nsc, new }),
        any::<u8>().prop_map(|block| Format::ReadBootBlock { block }),
        bytes().prop_map(Format::BootBlock),
        bytes().prop_map(Format::WriteBootBlock),
        Just(Format::EraseBoot),
        (bytes(), arr8()).prop_map(|(table, comp)| Format::CompressionTable { table, comp }),
        any::<u8>().prop_map(|xy| Format::Emergency { xy }),
    ]
}

fn bridge() -> impl Strategy<Value = Bridge> {
    prop_oneof![
        any::<u8>().prop_map(Bridge::SpiReceived),
        any::<u8>().prop_map(Bridge::SpiSend),
        any::<u8>().prop_map(Bridge::SciReceived),
        any::<u8>().prop_map(Bridge::SciSend),
        any::<u8>().prop_map(Bridge::ParallelRead),
        any::<u8>().prop_map(Bridge::ParallelWrite),
        any::<u8>().prop_map(Bridge::ParallelAddress),
        Just(Bridge::ParallelReadRequest),
    ]
}

fn message() -> impl Strategy<Value = Message> {
    prop_oneof![
        thread().prop_map(Message::Thread),
        Just(Message::CpuInfoRequest),
        (any::<[u8; 4]>(), arr8(), any::<[u8; 2]>(), arr8()).prop_map(
            |(a, serial, b, compression)| {
                Message::CpuInfo(CpuInfo {
                    quartz: a[0],
                    version_196: a[1],
                    version_pic: a[2],
                    pic_revision: a[3],
                    serial,
                    address: b[0],
                    supply: b[1],
                    compression,
                })
            }
        ),
        any::<[u8; 2]>().prop_map(|s| Message::Start(Start(s))),
        Just(Message::Stop),
        prop_oneof![
            Just(Power::PowerDown),
            Just(Power::Reset),
            Just(Power::PoweredDown),
            Just(Power::WasReset)
        ]
        .prop_map(Message::Power),
        (any::<u8>(), any::<u8>())
            .prop_map(|(bank, block)| Message::FlashReadRequest { bank, block }),
        bytes().prop_map(Message::FlashData),
        (any::<u8>(), any::<u8>(), bytes()).prop_map(|(bank, block, data)| Message::FlashWrite {
            bank,
            block,
            data
        }),
        any::<u8>().prop_map(|bank| Message::FlashErase { bank }),
        any::<u8>().prop_map(|block| Message::PicReadRequest { block }),
        bytes().prop_map(Message::PicData),
        (any::<u8>(), bytes()).prop_map(|(block, data)| Message::PicWrite { block, data }),
        Just(Message::EepromReadRequest),
        bytes().prop_map(Message::EepromData),
        bytes().prop_map(Message::EepromWrite),
        format().prop_map(Message::Format),
        (0u8..4, 0u8..4, any::<u8>()).prop_map(|(n, low, value)| Message::Pwm(Pwm::Set {
            n,
            low,
            value
        })),
        any::<u8>().prop_map(|v| Message::Pwm(Pwm::Dac(v))),
        bridge().prop_map(Message::Bridge),
        (0u8..8, 0u16..1024)
            .prop_map(|(channel, value)| Message::AdSample(AdSample::Pic { channel, value })),
        (0u8..8, 0u16..4096)
            .prop_map(|(channel, value)| Message::AdSample(AdSample::Virtual { channel, value })),
        (0u8..8, 0u8..8).prop_map(|(bank, config)| Message::CfgAdRequest { bank, config }),
        (any::<[u8; 18]>(), any::<[u8; 3]>()).prop_map(|(c196, pic)| Message::CfgAd { c196, pic }),
        any::<u8>().prop_map(|a| Message::Alert(Alert(a))),
        any::<u8>().prop_map(|m| Message::Msg(MsgCode(m))),
        Just(Message::Watchdog),
        (0u8..=0xEF, short(12)).prop_map(|(cmd, params)| Message::User { cmd, params }),
    ]
}

/// Messages and errors; the progress of PIC block writes (`Event::PicChunk`) is left out.
fn decode_all(d: &mut Decoder, bytes: &[u8]) -> Vec<Event> {
    bytes
        .iter()
        .enumerate()
        .filter_map(|(i, &b)| d.push(Nanos::new(i as u64 * 1000), b))
        .filter(|e| !matches!(e, Event::PicChunk { .. }))
        .collect()
}

fn decoder_for(m: &Message) -> Decoder {
    let mut d = Decoder::new();
    if let Message::User { cmd, params } = m {
        d.set_user_len(*cmd, params.len() as u8);
    }
    d
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn every_message_round_trips(m in message()) {
        let bytes = m.to_bytes().unwrap();
        let mut d = decoder_for(&m);
        prop_assert_eq!(decode_all(&mut d, &bytes), vec![Event::Message(m)]);
        prop_assert!(!d.in_frame());
    }

    #[test]
    fn adcont_round_trips_with_a_known_layout(data in proptest::collection::vec(any::<u8>(), 2..=256)) {
        let mut d = Decoder::new();
        d.set_adcont_len(Some(data.len()));
        let m = Message::AdCont(data);
        prop_assert_eq!(decode_all(&mut d, &m.to_bytes().unwrap()), vec![Event::Message(m)]);
    }

    #[test]
    fn garbage_never_panics_and_the_stream_recovers(
        garbage in proptest::collection::vec(any::<u8>(), 0..600),
        m in message(),
    ) {
        let mut d = decoder_for(&m);
        decode_all(&mut d, &garbage);
        // Whatever state the garbage left, a pause longer than the time-out resets the
        // decoder and the next frame decodes exactly.
        let t = Nanos::new(garbage.len() as u64 * 1000 + 10_000_000_000);
        let _ = d.poll(t);
        prop_assert!(!d.in_frame());
        let bytes = m.to_bytes().unwrap();
        let ev: Vec<_> = bytes
            .iter()
            .enumerate()
            .filter_map(|(i, &b)| d.push(t + Nanos::new(i as u64), b))
            .filter(|e| !matches!(e, Event::PicChunk { .. }))
            .collect();
        prop_assert_eq!(ev, vec![Event::Message(m)]);
    }

    #[test]
    fn a_wrong_complement_is_reported_and_the_next_frame_decodes(cmd in 0xF0u8.., bad in any::<u8>()) {
        // `bad` = 00h would pair with the watchdog's FFh: a protocol ambiguity, not a decoder bug.
        prop_assume!(bad != !cmd && bad != 0x00);
        let mut d = Decoder::new();
        let mut bytes = vec![cmd, bad];
        bytes.extend(Message::Watchdog.to_bytes().unwrap());
        let ev = decode_all(&mut d, &bytes);
        let wrong_complement = matches!(ev[0], Event::Error(buslab_cpu196::FrameError::WrongComplement { .. }));
        prop_assert!(wrong_complement);
        prop_assert_eq!(ev.last(), Some(&Event::Message(Message::Watchdog)));
    }
}
