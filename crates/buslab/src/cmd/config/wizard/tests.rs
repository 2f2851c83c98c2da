use std::collections::VecDeque;

use buslab_canbus::{AcceptanceFilter, ClockOut, Timing};

use super::*;
use crate::config::{Config, Lookup};

/// Answers from a script; a refused answer is recorded and the next one is taken, as a person
/// would answer again.
struct Script {
    answers: VecDeque<&'static str>,
    refused: Vec<String>,
    said: Vec<String>,
}

impl Script {
    fn new(answers: &[&'static str]) -> Self {
        Self {
            answers: answers.iter().copied().collect(),
            refused: Vec::new(),
            said: Vec::new(),
        }
    }

    fn next(&mut self, question: &str) -> &'static str {
        self.answers
            .pop_front()
            .unwrap_or_else(|| panic!("no answer left for {question:?}"))
    }
}

impl Prompter for Script {
    fn select(&mut self, question: &str, options: &[&str], start: usize) -> anyhow::Result<usize> {
        match self.next(question) {
            "" => Ok(start),
            a => Ok(options
                .iter()
                .position(|o| o.eq_ignore_ascii_case(a))
                .unwrap_or_else(|| panic!("{a:?} is not among {options:?} for {question:?}"))),
        }
    }

    fn text(
        &mut self,
        question: &str,
        default: &str,
        _: &str,
        check: Check,
    ) -> anyhow::Result<String> {
        loop {
            let answer = match self.next(question) {
                "" => default,
                a => a,
            };
            match check(answer) {
                Ok(()) => return Ok(answer.to_string()),
                Err(why) => self.refused.push(format!("{question}: {answer}: {why}")),
            }
        }
    }

    fn confirm(&mut self, question: &str, default: bool) -> anyhow::Result<bool> {
        Ok(match self.next(question) {
            "" => default,
            a => a.starts_with('y'),
        })
    }

    fn say(&mut self, text: &str) {
        self.said.push(text.to_string());
    }
}

/// Enter on every question: the mode, filter, timing (the bus's), OCR, clock out, divider,
/// bus, two identifiers, mail host, port, user, interval, manager interval, log file.
const ALL_DEFAULTS: [&str; 15] = [""; 15];

/// After the timing: OCR, clock out, divider, bus, two identifiers, mail host, port, user,
/// interval, manager interval, log file.
const REST: [&str; 12] = [""; 12];

#[test]
fn enter_everywhere_keeps_the_defaults() {
    let mut script = Script::new(&ALL_DEFAULTS);
    let settings = ask_all(&mut script, Settings::default()).unwrap();
    assert_eq!(settings, Settings::default());
    assert!(
        script.answers.is_empty() && script.refused.is_empty(),
        "{:?}",
        script.refused
    );
    // Nothing chosen for the controller: nothing of it is applied anywhere.
    assert!(settings.check().unwrap().controller_settings.is_empty());
}

#[test]
fn a_filter_from_the_ids_wanted_is_shown_as_the_ids_it_lets_through() {
    let mut answers = vec![
        "",
        "single",
        "the IDs to let through",
        "1FF-100", // a range that goes down: refused
        "100-1FF",
        "",
        "bit rate and sample point",
        "",
        "125 kHz", // refused, with what is accepted
        "125k",
        "-",
    ];
    answers.extend(REST);
    let mut script = Script::new(&answers);
    let s = ask_all(&mut script, Settings::default()).unwrap();
    let said = script.said.join("\n");
    assert!(
        said.contains("ACR=0x20000000 AMR=0x1FFFFFFF: exactly the 256 IDs asked for"),
        "{said}"
    );
    assert!(
        said.contains("standard 0x100..=0x1FF (256 IDs), data and remote frames"),
        "{said}"
    );
    let refused = script.refused.join("\n");
    assert!(
        refused.contains("1FF-100: \"1FF-100\": the range goes down"),
        "{refused}"
    );
    assert!(
        refused.contains("125 kHz: must be a bit rate 1..=1000000 bit/s: 125000, 125k"),
        "{refused}"
    );
    assert_eq!(s.bitrate, Some(125_000));
    let c = s.check().unwrap();
    assert_eq!(
        c.controller.filter,
        AcceptanceFilter::Single {
            code: [0x20, 0x00, 0x00, 0x00],
            mask: [0x1F, 0xFF, 0xFF, 0xFF]
        }
    );
}

#[test]
fn a_filter_not_kept_is_asked_again() {
    let mut answers = vec![
        "",
        "single",
        "ACR and AMR registers",
        "0x123",
        "0x001FFFFF",
        "n", // lets only 0x000 through: not kept
        "dual",
        "the IDs to let through",
        "120-12F 7FF",
        "",
        "",
    ];
    answers.extend(REST);
    let mut script = Script::new(&answers);
    let s = ask_all(&mut script, Settings::default()).unwrap();
    let said = script.said.join("\n");
    assert!(
        said.contains("standard 0x000, data and remote frames"),
        "{said}"
    );
    assert!(said.contains("exactly the 17 IDs asked for"), "{said}");
    assert_eq!(s.filter, FilterKind::Dual);
}

#[test]
fn a_basiccan_configuration_with_refused_answers_asked_again() {
    let mut script = Script::new(&[
        "BasicCAN",
        "basic",
        "ACR and AMR registers",
        "0x1E0", // 9 bits: refused
        "0xE0",
        "0x0F",
        "",
        "BTR0 and BTR1 registers",
        "12000000",
        "0x3F", // with 0x7F: a bit time the chip cannot do? keep the valid pair below
        "0x4D",
        "0xD9", // OCR test mode: refused
        "0x1A",
        "n",
        "tcp:nowhere", // refused
        "can0",
        "0x700",
        "", // mail_id 0x700 = loader_id: the pair is asked again
        "0x010",
        "0x701",
        "imap.example.org",
        "993",
        "jerry",
        "30", // no unit: refused
        "30s",
        "0s",
        "-",
    ]);
    let s = ask_all(&mut script, Settings::default()).unwrap();
    assert_eq!(script.answers.len(), 0, "every answer used");
    let refused = script.refused.join("\n");
    for expected in [
        "0x1E0: must be at most 0xFF here",
        "0xD9: must be an OCR value",
        "tcp:nowhere: unknown backend",
        "30: must be a duration with its unit",
    ] {
        assert!(refused.contains(expected), "{expected:?} not in\n{refused}");
    }
    assert!(
        script.said.iter().any(|t| t.contains("same identifier")),
        "{:?}",
        script.said
    );
    let said = script.said.join("\n");
    assert!(said.contains("standard 0x700..=0x77F (128 IDs)"), "{said}");
    let c: Config = s.check().unwrap();
    assert_eq!(c.controller.mode, CanMode::Basic);
    assert_eq!(
        c.controller.filter,
        AcceptanceFilter::Basic {
            code: 0xE0,
            mask: 0x0F
        }
    );
    assert_eq!(
        c.controller.timing,
        Timing::Registers {
            btr0: 0x3F,
            btr1: 0x4D
        }
    );
    assert_eq!(c.controller.output_control, 0x1A);
    assert_eq!(c.controller.clock_out, ClockOut::Off);
    assert_eq!(c.bus_name, "can0");
    assert_eq!((c.loader_id, c.mail_id), (0x010, 0x701));
    assert_eq!(c.mail.host.as_deref(), Some("imap.example.org"));
    assert_eq!(c.mail.interval, std::time::Duration::from_secs(30));
    assert_eq!(c.log_file, None);
}

#[test]
fn a_timing_the_chip_cannot_do_repeats_the_timing_step() {
    let mut answers = vec!["", "", "bit rate and sample point", "", "3", "-"];
    // Again, with a bit rate it can do and a sample point.
    answers.extend(["", "", "125000", "75"]);
    answers.extend(REST);
    let mut script = Script::new(&answers);
    let s = ask_all(&mut script, Settings::default()).unwrap();
    assert!(
        script
            .said
            .iter()
            .any(|t| t.contains("This timing cannot be used")),
        "{:?}",
        script.said
    );
    assert_eq!((s.bitrate, s.sample_point), (Some(125_000), Some(750)));
}

#[test]
fn the_file_written_reads_back_as_the_configuration_answered() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sub").join("buslab.toml");
    let mut answers = vec![
        "PeliCAN",
        "dual",
        "ACR and AMR registers",
        "0x12345678",
        "0x000000FF",
        "",
    ];
    answers.extend(["BTR0 and BTR1 registers", "", "0x01", "0x1C"]);
    answers.extend(REST);
    answers.push("y");
    let mut script = Script::new(&answers);
    let settings = ask_all(&mut script, Settings::default()).unwrap();
    write(&mut script, &settings, &path).unwrap();
    let lookup = Lookup {
        file: Some(path.clone()),
        ..Lookup::default()
    };
    let loaded = config::load(&lookup, &|_| None, dir.path(), None).unwrap();
    let mut expected = settings.check().unwrap();
    // Read from the file, the keys written are given: the filter and the timing are applied;
    // the mode, OCR and clock out kept their defaults and were not written.
    let applied = loaded.config.controller_settings;
    assert_eq!(applied.filter, Some(expected.controller.filter));
    assert_eq!(applied.timing.map(|t| (t.btr0, t.btr1)), Some((0x01, 0x1C)));
    assert_eq!(
        (applied.mode, applied.output_control, applied.clock_out),
        (None, None, None)
    );
    expected.controller_settings = applied;
    assert_eq!(loaded.config, expected);
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(
        text.contains("btr0 = 0x01") && !text.contains("bitrate ="),
        "{text}"
    );
    let leftovers: Vec<_> = std::fs::read_dir(path.parent().unwrap()).unwrap().collect();
    assert_eq!(leftovers.len(), 1, "no temporary file left");
}

#[test]
fn declining_at_the_end_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("buslab.toml");
    let mut script = Script::new(&["n"]);
    write(&mut script, &Settings::default(), &path).unwrap();
    assert!(!path.exists());
}
