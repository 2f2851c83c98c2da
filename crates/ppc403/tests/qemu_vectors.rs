//! The core against QEMU's PowerPC emulator (`qemu-ppc`) on the committed vectors
//! (`tests/data/qemu_vectors.txt`, made by `examples/qemu_vectors.rs generate`), replayed
//! without qemu: each vector is a machine state, 1–8 user-level integer instructions at their
//! address, and the registers and scratch memory qemu-ppc left after them.
//! `scripts/ppc403-vs-qemu.sh` runs a fresh random sample in qemu-ppc itself.

mod qemu_cases;

use std::collections::BTreeMap;

use qemu_cases::{Vector, all_mnemonics, check, disassemble};

const FILE: &str = include_str!("data/qemu_vectors.txt");
/// Every mnemonic the generator makes appears in at least this many committed cases.
const LEAST_PER_MNEMONIC: usize = 48;

fn committed() -> Vec<Vector> {
    FILE.lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .map(|l| Vector::parse(l).unwrap_or_else(|e| panic!("{e}")))
        .collect()
}

fn mnemonics(v: &Vector) -> Vec<String> {
    let c = &v.case;
    let mut names: Vec<String> = c
        .code
        .iter()
        .enumerate()
        .map(|(i, &w)| disassemble(w, c.addr + 4 * i as u32).0)
        .collect();
    names.sort();
    names.dedup();
    names
}

#[test]
fn every_committed_vector_matches_qemu() {
    let vectors = committed();
    // mnemonic -> (cases with it, cases with it that differ)
    let mut tally: BTreeMap<String, (usize, usize)> = BTreeMap::new();
    let mut failures = Vec::new();
    for v in &vectors {
        let result = check(v);
        for m in mnemonics(v) {
            let e = tally.entry(m).or_default();
            e.0 += 1;
            e.1 += usize::from(result.is_err());
        }
        if let Err(e) = result {
            failures.push(e);
        }
    }
    let thin: Vec<String> = all_mnemonics()
        .into_iter()
        .filter(|m| tally.get(m).map_or(0, |t| t.0) < LEAST_PER_MNEMONIC)
        .collect();
    assert!(
        thin.is_empty(),
        "every mnemonic needs {LEAST_PER_MNEMONIC} cases; too few of: {}",
        thin.join(" ")
    );
    let mut table = String::new();
    for (i, (m, (all, bad))) in tally.iter().enumerate() {
        let cell = if *bad > 0 {
            format!("{m} {all} ({bad} differ)")
        } else {
            format!("{m} {all}")
        };
        table.push_str(&format!("{cell:<22}"));
        if i % 6 == 5 {
            table.push('\n');
        }
    }
    println!(
        "compared {} vectors over {} mnemonics: {} agree\ncases per mnemonic:\n{table}",
        vectors.len(),
        tally.len(),
        vectors.len() - failures.len()
    );
    assert!(
        failures.is_empty(),
        "{} of {} vectors differ from qemu-ppc (cases per mnemonic, differing in brackets:\n{table})\n\
         the first ones:\n{}",
        failures.len(),
        vectors.len(),
        failures
            .iter()
            .take(15)
            .cloned()
            .collect::<Vec<_>>()
            .join("\n")
    );
}

#[test]
fn the_committed_vectors_branch_backwards_too() {
    // Relative `b` and `bc` with a negative displacement (loops counted by CTR, detours):
    // the sign extension of LI and BD is compared, not only forward jumps.
    let (mut b, mut bc) = (0, 0);
    for v in committed() {
        for &w in &v.case.code {
            let relative = w & 2 == 0;
            match w >> 26 {
                18 if relative && w & 0x0200_0000 != 0 => b += 1,
                16 if relative && w & 0x8000 != 0 => bc += 1,
                _ => {}
            }
        }
    }
    assert!(b >= 48 && bc >= 48, "{b} backward b, {bc} backward bc");
}

#[test]
fn a_vector_that_does_not_match_is_reported_with_its_instructions() {
    let good = committed()
        .into_iter()
        .find(|v| v.case.code.len() == 1)
        .expect("a case of one instruction");
    assert_eq!(check(&good), Ok(()));
    let text = disassemble(good.case.code[0], good.case.addr).1;
    let mut wrong = good.clone();
    wrong.after.gpr[7] ^= 1;
    wrong.after.scratch[3] ^= 0x80;
    let err = check(&wrong).unwrap_err();
    assert!(err.contains(&text), "{err} should show {text}");
    assert!(err.contains("r7: qemu"), "{err}");
    assert!(err.contains("mem 7003: qemu"), "{err}");
}

#[test]
fn the_vector_lines_are_rebuilt_exactly() {
    for line in FILE.lines().filter(|l| !l.starts_with('#')).take(500) {
        let v = Vector::parse(line).unwrap();
        assert_eq!(v.line(), line);
    }
}

#[test]
fn garbage_lines_are_refused_by_name() {
    for (line, says) in [
        ("", "not SEED ADDR"),
        ("zz 00002000 7c000214 | in | out", "seed"),
        ("1 00002000 | in | out", "1 to 8 code words"),
        ("1 00002002 7c000214 | in | out", "word-aligned"),
        ("1 00002000 7c000214 | in r32=0 | out", "no register r32"),
        (
            "1 00002000 7c000214 | in | out m6fff=00",
            "outside the scratch area",
        ),
        ("1 00002000 7c000214 | in | out m7000=0", "odd or empty"),
        ("1 00002000 7c000214 | in | out pc=0", "unknown name"),
    ] {
        let err = Vector::parse(line).err().unwrap_or_default();
        assert!(err.contains(says), "{line:?}: {err:?} should say {says:?}");
    }
}
