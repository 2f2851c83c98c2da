//! candump log parsing and writing on one core (the target: 10 M frames/s parsed), and CAN FD
//! lines (tried after the classic parse: classic lines must not pay for them).
//! `cargo bench -p buslab-logs --bench candump`; bench/logs.sh prints the frames/s.

use std::hint::black_box;
use std::io::Cursor;
use std::time::Duration;

use buslab_logs::Timestamp;
use buslab_logs::candump::{Reader, Writer};
use buslab_logs::{Message, Record};
use criterion::{Criterion, Throughput, criterion_group, criterion_main};

/// `n` lines like candump's: mixed standard and extended IDs, 0..8 bytes, two interfaces.
pub fn log(n: u64) -> Vec<u8> {
    let mut w = Writer::new(Vec::new());
    let mut seed = 0x2545_F491_4F6C_DD1Du64;
    for i in 0..n {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        let len = (seed % 9) as usize;
        let text = if seed & 0x100 != 0 {
            format!(
                "{:08X}#{}",
                (seed >> 8) & 0x1FFF_FFFF,
                hex(&seed.to_le_bytes()[..len])
            )
        } else {
            format!(
                "{:03X}#{}",
                (seed >> 8) & 0x7FF,
                hex(&seed.to_le_bytes()[..len])
            )
        };
        w.write(&Message {
            at: Timestamp::since_epoch(Duration::from_micros(1_700_000_000_000_000 + i * 137)),
            channel: if i % 5 == 0 { "vcan1" } else { "vcan0" }.into(),
            record: Record::Frame(text.parse().unwrap()),
            direction: None,
        })
        .unwrap();
    }
    w.into_inner()
}

/// `n` CAN FD lines: every FD length in turn, BRS/ESI varying, standard and extended IDs.
pub fn fd_log(n: u64) -> Vec<u8> {
    let mut w = Writer::new(Vec::new());
    for i in 0..n {
        let len = buslab_can::FD_LENGTHS[(i % 16) as usize];
        let data: Vec<u8> = (0..len).map(|k| (k as u64 ^ i) as u8).collect();
        let text = if i % 3 == 0 {
            format!("{:08X}##{}{}", 0x1ABC_0000 + i % 0x1000, i % 4, hex(&data))
        } else {
            format!("{:03X}##{}{}", i % 0x7FF, i % 4, hex(&data))
        };
        w.write(&Message {
            at: Timestamp::since_epoch(Duration::from_micros(1_700_000_000_000_000 + i * 137)),
            channel: "can0".into(),
            record: Record::Fd(text.parse().unwrap()),
            direction: None,
        })
        .unwrap();
    }
    w.into_inner()
}

fn hex(b: &[u8]) -> String {
    b.iter().map(|x| format!("{x:02X}")).collect()
}

fn bench(c: &mut Criterion) {
    const N: u64 = 200_000;
    let input = log(N);
    let mut group = c.benchmark_group("candump");
    group.throughput(Throughput::Elements(N));
    group.bench_function("parse", |b| {
        b.iter(|| {
            let mut reader = Reader::new(Cursor::new(&input[..]));
            let mut entry = Message::default();
            let mut n = 0u64;
            while reader.read_into(&mut entry).unwrap() {
                n += 1;
            }
            assert_eq!(n, N);
            black_box(entry)
        })
    });
    let fd_input = fd_log(N);
    group.bench_function("parse FD", |b| {
        b.iter(|| {
            let mut reader = Reader::new(Cursor::new(&fd_input[..]));
            let mut entry = Message::default();
            let mut n = 0u64;
            while reader.read_into(&mut entry).unwrap() {
                n += 1;
            }
            assert_eq!(n, N);
            black_box(entry)
        })
    });
    let mut entries = Vec::new();
    let mut reader = Reader::new(Cursor::new(&input[..]));
    let mut entry = Message::default();
    while reader.read_into(&mut entry).unwrap() {
        entries.push(entry.clone());
    }
    group.bench_function("write", |b| {
        let mut out = Vec::with_capacity(input.len());
        b.iter(|| {
            out.clear();
            let mut w = Writer::new(&mut out);
            for e in &entries {
                w.write(e).unwrap();
            }
            black_box(out.len())
        })
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
