//! The S-record reader against what a fuzzer would throw at it (the workspace has no `fuzz/`
//! yet): arbitrary bytes and arbitrary record-like lines never panic, files written by
//! `srec::write` read back the same, and any single hex digit changed after the record type is
//! caught and named with its line.

use buslab_loader::memory::MemoryImage;
use buslab_loader::srec::{self, Problem};
use proptest::prelude::*;

/// Non-overlapping runs inside a 32-bit space.
fn runs() -> impl Strategy<Value = Vec<(u32, Vec<u8>)>> {
    proptest::collection::vec(
        (0u32..0x1000, proptest::collection::vec(any::<u8>(), 1..100)),
        0..8,
    )
    .prop_map(|chunks| {
        let mut at = 0x0002_0000u32;
        chunks
            .into_iter()
            .map(|(gap, data)| {
                let run = (at + gap, data);
                at += gap + run.1.len() as u32 + 1;
                run
            })
            .collect()
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..2000)) {
        let _ = srec::parse(&bytes);
    }

    #[test]
    fn record_like_lines_never_panic(lines in proptest::collection::vec("[Ss][0-9A-Za-z][0-9A-Fa-f]{0,40}[G \r]?", 0..40)) {
        let text = lines.join("\n");
        if let Err(errors) = srec::parse(text.as_bytes()) {
            prop_assert!(errors.count() > 0);
            prop_assert!(errors.errors.iter().all(|e| e.line >= 1 && e.line <= lines.len()));
        }
    }

    #[test]
    fn written_files_read_back(runs in runs(), start in proptest::option::of(any::<u32>())) {
        let text = srec::write(b"prop", runs.iter().map(|(a, d)| (*a, &d[..])), start);
        let program = srec::parse(&text).unwrap();
        prop_assert_eq!(program.start, start);
        prop_assert!(program.overlaps().is_empty());
        let image = MemoryImage::from_program(&program);
        for (address, data) in &runs {
            prop_assert_eq!(&image.read(*address, data.len()), data);
        }
    }

    #[test]
    fn any_changed_digit_is_caught(runs in runs(), pick in any::<prop::sample::Index>(), delta in 1u8..16) {
        prop_assume!(!runs.is_empty());
        let mut text = srec::write(b"x", runs.iter().map(|(a, d)| (*a, &d[..])), Some(0x20000));
        // Hex digits after `S` and the type digit of each line.
        let mut digits = Vec::new();
        let mut col = 0;
        let mut line = 1;
        for (i, &b) in text.iter().enumerate() {
            if b == b'\n' {
                col = 0;
                line += 1;
                continue;
            }
            if col >= 2 {
                digits.push((i, line));
            }
            col += 1;
        }
        let (at, line) = digits[pick.index(digits.len())];
        let value = u8::from_str_radix(std::str::from_utf8(&text[at..=at]).unwrap(), 16).unwrap();
        text[at] = format!("{:X}", (value + delta) % 16).as_bytes()[0];
        let errors = srec::parse(&text).unwrap_err();
        let first = errors.first().unwrap();
        prop_assert_eq!(first.line, line);
        prop_assert!(
            matches!(first.problem, Problem::Checksum { .. } | Problem::CountMismatch { .. } | Problem::CountTooSmall { .. }),
            "{}", first
        );
    }
}

#[test]
fn a_large_garbage_file_gives_a_bounded_report() {
    let mut garbage = Vec::new();
    for i in 0..50_000u32 {
        garbage.extend_from_slice(format!("S1{i:08X}junk\n").as_bytes());
    }
    let errors = srec::parse(&garbage).unwrap_err();
    assert_eq!(errors.errors.len(), srec::MAX_ERRORS);
    assert_eq!(errors.count(), 50_000);
    assert!(errors.to_string().ends_with(&format!(
        "… and {} more bad lines",
        50_000 - srec::MAX_ERRORS
    )));
    // Binary noise, NULs and a line far longer than any record.
    let mut noise: Vec<u8> = (0..=255u8).cycle().take(100_000).collect();
    noise.extend(std::iter::repeat_n(b'S', 10_000));
    assert!(srec::parse(&noise).is_err());
}
