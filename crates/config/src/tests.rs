use std::collections::HashMap;
use std::fs;
use std::path::Path;
use std::time::Duration;

use buslab_canbus::{AcceptanceFilter, CanMode, ClockOut, Timing};

use super::*;

/// Loads with `vars` as the whole environment, `cwd` as the current directory and `user` as
/// the user's configuration file.
fn load_with(
    lookup: &Lookup,
    vars: &[(&str, &str)],
    cwd: &Path,
    user: Option<&Path>,
) -> Result<Loaded, ConfigError> {
    let vars: HashMap<String, String> = vars
        .iter()
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect();
    load(lookup, &|k| vars.get(k).cloned(), cwd, user)
}

fn file_config(text: &str) -> Result<Loaded, ConfigError> {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("buslab.toml");
    fs::write(&path, text).unwrap();
    let lookup = Lookup {
        file: Some(path),
        ..Lookup::default()
    };
    load_with(&lookup, &[], dir.path(), None)
}

fn error(text: &str) -> String {
    file_config(text).unwrap_err().to_string()
}

#[test]
fn the_defaults_are_buslab_s_bus_and_the_seed_s_identifiers() {
    let c = Config::default();
    assert_eq!(c.bus.to_string(), buslab_backends::DEFAULT_URL);
    assert_eq!(c.bus_name, "vcan0");
    assert_eq!((c.loader_id, c.mail_id), (0, 0x700));
    assert_eq!(c.log_file, None);
    assert_eq!(c.mail.port, 143);
    assert_eq!(c.mail.interval, Duration::from_secs(60));
    assert_eq!(c.manager_poll_interval, Duration::from_millis(1));
    assert_eq!(c.controller.mode, CanMode::Peli);
    // No bit rate of its own: the bus's (or the adapter's) stays; nothing is applied.
    assert_eq!(c.controller_bitrate(), None);
    assert!(c.controller_settings.is_empty());
    assert_eq!(c.controller.filter, AcceptanceFilter::AcceptAll);
    assert_eq!(c.controller.output_control, 0xDA);
    assert_eq!(c.controller.clock_out, ClockOut::Divider(2));
}

#[test]
fn a_whole_file_is_read_into_typed_values() {
    let loaded = file_config(
        r#"
bus = "can0"
log_file = "frames.log"
loader_id = 0x010
mail_id = 0x701

[mail]
host = "imap.example.org"
port = 993
user = "jerry"
interval = "30s"

[manager]
poll_interval = "0s"

[controller]
mode = "basiccan"
crystal_hz = 24_000_000
btr0 = 0x07
btr1 = 0x4D
filter = "basic"
acceptance_code = 0xE0
acceptance_mask = 0x0F
output_control = 0x1A
clock_out = false
"#,
    )
    .unwrap();
    let c = &loaded.config;
    assert_eq!(c.bus.to_string(), "socketcan:can0");
    assert_eq!(c.log_file.as_deref(), Some(Path::new("frames.log")));
    assert_eq!((c.loader_id, c.mail_id), (0x010, 0x701));
    assert_eq!(c.mail.host.as_deref(), Some("imap.example.org"));
    assert_eq!(c.mail.port, 993);
    assert_eq!(c.mail.user.as_deref(), Some("jerry"));
    assert_eq!(c.mail.interval, Duration::from_secs(30));
    assert_eq!(c.manager_config().poll_interval, Duration::ZERO);
    let chip = &c.controller;
    assert_eq!(chip.mode, CanMode::Basic);
    assert_eq!(chip.crystal_hz, 24_000_000);
    assert_eq!(
        chip.timing,
        Timing::Registers {
            btr0: 0x07,
            btr1: 0x4D
        }
    );
    assert_eq!(
        chip.filter,
        AcceptanceFilter::Basic {
            code: 0xE0,
            mask: 0x0F
        }
    );
    assert_eq!(chip.output_control, 0x1A);
    assert_eq!(chip.clock_out, ClockOut::Off);
    // 12 MHz CAN clock / (8 × 20 quanta).
    assert_eq!(c.controller_bitrate(), Some(75_000));
    // Every part was given, so every part is applied where a command opens a bus.
    let applied = &c.controller_settings;
    assert_eq!(applied.mode, Some(buslab_canbus::ControllerMode::BasicCan));
    assert_eq!(applied.filter, Some(chip.filter));
    assert_eq!(applied.output_control, Some(0x1A));
    assert_eq!(applied.clock_out, Some(ClockOut::Off));
    assert_eq!(
        applied.timing.map(|t| (t.crystal_hz, t.btr0, t.btr1)),
        Some((24_000_000, 0x07, 0x4D))
    );
    match loaded.source("controller.btr1") {
        Some(Source::File { line, .. }) => assert_eq!(*line, 20),
        other => panic!("{other:?}"),
    }
    assert_eq!(loaded.source("controller.bitrate"), Some(&Source::Default));
}

#[test]
fn every_bad_value_is_named_with_its_file_line_key_and_what_is_allowed() {
    for (text, expected) in [
        (
            "mail_id = 0x7F5",
            ":1: mail_id = 0x7F5: must be an 11-bit identifier 0x000..=0x7EF",
        ),
        (
            "\n\nloader_id = \"0x10\"",
            ":3: loader_id = \"0x10\": must be an 11-bit",
        ),
        (
            "[mail]\nport = 0",
            ":2: mail.port = 0: must be a TCP port 1..=65535",
        ),
        (
            "[mail]\ninterval = 60",
            "mail.interval = 60: must be a duration with its unit",
        ),
        (
            "[manager]\npoll_interval = \"11s\"",
            "manager.poll_interval = \"11s\": must be",
        ),
        (
            "[controller]\nmode = \"CAN FD\"",
            "controller.mode = \"CAN FD\": must be \"PeliCAN\", \"BasicCAN\", \"listen-only\" or \"self-test\"",
        ),
        (
            "[controller]\nclock_divider = 3",
            "controller.clock_divider = 3: must be 1, 2, 4",
        ),
        (
            "[controller]\noutput_control = 0xD9",
            "controller.output_control = 0xD9: must be an OCR value",
        ),
        (
            "[controller]\nsample_point = 99",
            "controller.sample_point = 99: must be a sample point in per cent, 50..=95",
        ),
        (
            "[controller]\ncrystal_hz = 40000000",
            "controller.crystal_hz = 40000000: must be the crystal frequency",
        ),
        ("bus = \"tcp:x\"", "bus = \"tcp:x\": unknown backend"),
        (
            "bus = 3",
            "bus = 3: must be a string in quotes, not an integer",
        ),
        (
            "[bus]\nx = 1",
            "bus = [bus]: must be a string in quotes, not a table",
        ),
        ("mail_id = 0x0AA", "mail_id = 0x0AA: MoniCAN refuses it"),
        (
            "[controller]\nbitrate = 3",
            "controller.bitrate = 3: bit rate 3 bit/s cannot be reached",
        ),
    ] {
        let err = error(text);
        assert!(err.contains("buslab.toml"), "{text:?} → {err}");
        assert!(
            err.contains(expected),
            "{text:?} → {err}\nexpected: {expected}"
        );
    }
}

#[test]
fn keys_that_contradict_each_other_are_refused_with_both_sources() {
    let err = error("[controller]\nbitrate = 125000\nbtr0 = 7\nbtr1 = 0x4D");
    assert!(
        err.contains("controller.bitrate") && err.contains("controller.btr0"),
        "{err}"
    );
    assert!(
        err.contains("buslab.toml:2") && err.contains("buslab.toml:3"),
        "{err}"
    );
    let err = error("[controller]\nbtr0 = 7");
    assert!(err.contains("btr1 is missing"), "{err}");
    let err = error("[controller]\nfilter = \"basic\"");
    assert!(
        err.contains("controller.filter") && err.contains("controller.mode"),
        "{err}"
    );
    let err = error("[controller]\nacceptance_code = 1");
    assert!(err.contains("\"accept-all\" has no code or mask"), "{err}");
    let err =
        error("[controller]\nmode = \"BasicCAN\"\nfilter = \"basic\"\nacceptance_code = 0x100");
    assert!(
        err.contains("acceptance_code = 0x100: must be 0x00..=0xFF"),
        "{err}"
    );
    let err = error("loader_id = 0x700");
    assert!(
        err.contains("mail_id") && err.contains("same identifier"),
        "{err}"
    );
}

#[test]
fn unknown_keys_are_errors_with_a_suggestion() {
    let err = error("[mail]\nhots = \"x\"");
    assert!(
        err.ends_with("unknown key mail.hots (did you mean mail.host?)"),
        "{err}"
    );
    let err = error("mailsleepingtime = 60");
    assert!(
        err.contains("did you mean mail.interval, JerryCAN's mailsleepingtime?"),
        "{err}"
    );
    let err = error("[controler]\nbitrate = 1");
    assert!(
        err.ends_with(":1: unknown key controler (did you mean [controller]?)"),
        "{err}"
    );
    let err = error("[mail.extra]\nx = 1");
    assert!(err.contains("unknown key mail.extra"), "{err}");
    let err = error("bus = \"vcan0\"\nbus = \"can0\"");
    assert!(
        err.contains("buslab.toml:2:1"),
        "a TOML error has its line: {err}"
    );
}

#[test]
fn the_file_is_looked_up_in_order_and_only_the_first_is_read() {
    let dir = tempfile::tempdir().unwrap();
    let write = |name: &str, bus: &str| {
        let path = dir.path().join(name);
        fs::create_dir_all(path.parent().unwrap()).unwrap();
        fs::write(&path, format!("bus = \"{bus}\"\n")).unwrap();
        path
    };
    let cwd = dir.path().join("work");
    let user = write("home/buslab/buslab.toml", "user0");
    fs::create_dir_all(&cwd).unwrap();
    let bus = |lookup: &Lookup, vars: &[(&str, &str)]| {
        let loaded = load_with(lookup, vars, &cwd, Some(&user)).unwrap();
        (loaded.config.bus_name.clone(), loaded.file.map(|(_, f)| f))
    };
    let none = Lookup::default();
    assert_eq!(
        bus(&none, &[]),
        ("user0".into(), Some(Found::UserDirectory))
    );
    write("work/buslab.toml", "here0");
    assert_eq!(
        bus(&none, &[]),
        ("here0".into(), Some(Found::CurrentDirectory))
    );
    let env_file = write("env.toml", "env0");
    let env_var = [("BUSLAB_CONFIG", env_file.to_str().unwrap())];
    assert_eq!(
        bus(&none, &env_var),
        ("env0".into(), Some(Found::Environment))
    );
    let flag = Lookup {
        file: Some(write("flag.toml", "flag0")),
        ..Lookup::default()
    };
    assert_eq!(
        bus(&flag, &env_var),
        ("flag0".into(), Some(Found::CommandLine))
    );
    let no_file = Lookup {
        no_file: true,
        ..Lookup::default()
    };
    assert_eq!(bus(&no_file, &env_var), ("vcan0".into(), None));
    // A file that is named must exist.
    let missing = Lookup {
        file: Some(dir.path().join("missing.toml")),
        ..Lookup::default()
    };
    let err = load_with(&missing, &[], &cwd, None)
        .unwrap_err()
        .to_string();
    assert!(err.contains("missing.toml (from --config)"), "{err}");
}

#[test]
fn the_environment_overrides_the_file_and_set_overrides_both() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("b.toml");
    fs::write(&path, "mail_id = 0x701\n[mail]\nhost = \"file.example\"\n").unwrap();
    let lookup = Lookup {
        file: Some(path.clone()),
        sets: vec!["mail.host=cli.example".into()],
        ..Lookup::default()
    };
    let vars = [
        ("BUSLAB_MAIL_HOST", "env.example"),
        ("BUSLAB_MAIL_ID", "0x702"),
        ("BUSLAB_MAIL_PASSWORD", "s3cret"),
        ("BUSLAB_CONTROLLER_MODE", ""),
    ];
    let loaded = load_with(&lookup, &vars, dir.path(), None).unwrap();
    let c = &loaded.config;
    assert_eq!(c.mail.host.as_deref(), Some("cli.example"));
    assert_eq!(c.mail_id, 0x702);
    assert_eq!(
        c.mail.password.as_ref().map(Password::expose),
        Some("s3cret")
    );
    assert_eq!(loaded.source("mail.host"), Some(&Source::CommandLine));
    assert_eq!(
        loaded.source("mail_id"),
        Some(&Source::Env("BUSLAB_MAIL_ID".into()))
    );
    assert_eq!(
        loaded.source("controller.mode"),
        Some(&Source::Default),
        "empty = unset"
    );
    let bad_set = Lookup {
        sets: vec!["mail.hots=x".into()],
        ..Lookup::default()
    };
    let err = load_with(&bad_set, &[], dir.path(), None)
        .unwrap_err()
        .to_string();
    assert_eq!(
        err,
        "--set: unknown key mail.hots (did you mean mail.host?)"
    );
}

#[test]
fn the_password_comes_from_the_environment_only_and_is_never_shown() {
    let err = error("[mail]\npassword = \"hunter2\"\n");
    assert!(
        err.contains("buslab.toml:2") && err.contains("BUSLAB_MAIL_PASSWORD"),
        "{err}"
    );
    assert!(!err.contains("hunter2"), "{err}");
    let dir = tempfile::tempdir().unwrap();
    let set = Lookup {
        sets: vec!["mail.password=hunter2".into()],
        ..Lookup::default()
    };
    let err = load_with(&set, &[], dir.path(), None)
        .unwrap_err()
        .to_string();
    assert!(err.contains("--set") && !err.contains("hunter2"), "{err}");
    let loaded = load_with(
        &Lookup::default(),
        &[("BUSLAB_MAIL_PASSWORD", "hunter2")],
        dir.path(),
        None,
    )
    .unwrap();
    let shown = render_show(&loaded);
    assert!(!shown.contains("hunter2"), "{shown}");
    assert!(shown.contains("from $BUSLAB_MAIL_PASSWORD"), "{shown}");
    assert!(!format!("{:?}", loaded.config).contains("hunter2"));
}

#[test]
fn mqtt_credentials_come_from_the_file_or_the_environment_never_set_and_are_not_shown() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("buslab.toml");
    fs::write(
        &path,
        "[mqtt]\nusername = \"bench\"\npassword = \"hunter2\"\n",
    )
    .unwrap();
    let lookup = Lookup {
        file: Some(path.clone()),
        ..Lookup::default()
    };
    let loaded = load_with(&lookup, &[], dir.path(), None).unwrap();
    let c = loaded.config.mqtt_credentials.clone().unwrap();
    let from_file = format!("{}:2 and {}:3", path.display(), path.display());
    assert_eq!(
        c,
        buslab_backends::mqtt::Credentials::new("bench", "hunter2", &from_file)
    );
    let shown = render_show(&loaded);
    assert!(!shown.contains("hunter2"), "{shown}");
    assert!(shown.contains("# password = (set, not shown)"), "{shown}");
    assert!(!format!("{:?}", loaded).contains("hunter2"));
    // The wizard's file keeps it (it rewrites the file it read).
    assert!(render_file(&loaded.settings).contains("password = \"hunter2\""));

    // The environment overrides the file.
    let vars = [("BUSLAB_MQTT_PASSWORD", "env-secret")];
    let loaded = load_with(&lookup, &vars, dir.path(), None).unwrap();
    let c = loaded.config.mqtt_credentials.unwrap();
    assert_eq!(c.username, "bench");
    assert_eq!(
        c,
        buslab_backends::mqtt::Credentials::new(
            "bench",
            "env-secret",
            format!("{}:2 and environment BUSLAB_MQTT_PASSWORD", path.display())
        )
    );

    // Never from the command line, the user name either; the value is not repeated.
    for set in ["mqtt.password=hunter2", "mqtt.username=bench"] {
        let set = Lookup {
            sets: vec![set.into()],
            ..Lookup::default()
        };
        let err = load_with(&set, &[], dir.path(), None)
            .unwrap_err()
            .to_string();
        assert!(
            err.starts_with("--set mqtt.") && err.contains("[mqtt]") && !err.contains("hunter2"),
            "{err}"
        );
    }

    // One without the other; a bad password is not printed back.
    let err = error("[mqtt]\nusername = \"bench\"\n");
    assert!(
        err.contains("mqtt.username") && err.contains("the password is missing"),
        "{err}"
    );
    let err = error("[mqtt]\nusername = \"bench\"\npassword = \"bad\\u0007\"\n");
    assert!(
        err.contains("buslab.toml:3") && err.contains("(not shown)") && !err.contains("bad"),
        "{err}"
    );
}

#[test]
fn only_regular_files_of_a_bounded_size_are_read() {
    let dir = tempfile::tempdir().unwrap();
    let read = |path: &Path| {
        let lookup = Lookup {
            file: Some(path.to_path_buf()),
            ..Lookup::default()
        };
        load_with(&lookup, &[], dir.path(), None)
            .unwrap_err()
            .to_string()
    };
    assert!(
        read(dir.path()).contains("a folder"),
        "{}",
        read(dir.path())
    );
    let big = dir.path().join("big.toml");
    fs::write(&big, "#".repeat(MAX_FILE_BYTES as usize + 1)).unwrap();
    assert!(read(&big).contains("larger than"), "{}", read(&big));
    let fifo = dir.path().join("fifo.toml");
    nix::unistd::mkfifo(&fifo, nix::sys::stat::Mode::S_IRWXU).unwrap();
    assert!(read(&fifo).contains("a FIFO"), "{}", read(&fifo));
}

#[test]
fn what_show_prints_and_the_wizard_writes_reads_back_the_same() {
    let loaded = file_config(
        "bus = \"can1\"\n[mail]\nuser = \"jerry\"\n[controller]\nmode = \"BasicCAN\"\nfilter = \"basic\"\nacceptance_code = 0x12\nbitrate = 125000\nsample_point = 75\n",
    )
    .unwrap();
    for text in [render_show(&loaded), render_file(&loaded.settings)] {
        let again = file_config(&text).unwrap_or_else(|e| panic!("{e}\n{text}"));
        assert_eq!(again.config, loaded.config, "{text}");
    }
    // Keys that say nothing in this configuration are shown as comments, so the text still
    // reads back.
    let defaults = load_with(&Lookup::default(), &[], Path::new("/"), None).unwrap();
    let shown = render_show(&defaults);
    assert!(
        shown.contains("# acceptance_code = 0x00000000 (not used)"),
        "{shown}"
    );
    assert_eq!(
        file_config(&shown).unwrap().config,
        Config::default(),
        "{shown}"
    );
    let shown = render_show(&loaded);
    assert!(
        shown.contains("registers: CDR=0x00 OCR=0xDA ACR=12 AMR=FF"),
        "{shown}"
    );
    assert!(shown.contains("125000 bit/s"), "{shown}");
}

#[test]
fn garbage_files_are_errors_not_panics() {
    let deep = format!("a = {}{}", "[".repeat(5000), "]".repeat(5000));
    for text in [
        "\u{0}\u{1}\u{7f}",
        "[mail\nhost = 1",
        "mail_id = 0x7FFFFFFFFFFFFFFFFFFFFFFF",
        "mail_id = -0",
        "controller.sample_point = nan",
        "[controller]\nsample_point = inf",
        "[[mail]]\nhost = \"x\"",
        "bus = \"\"",
        "[mail]\ninterval = \"99999999999999999999999h\"",
        &deep,
    ] {
        let path = Path::new("buslab.toml");
        match load_text(Some((path, Found::CommandLine, text)), &|_| None, &[]) {
            Ok(loaded) => panic!("{text:?} accepted: {:?}", loaded.settings),
            Err(e) => assert!(!e.to_string().is_empty()),
        }
    }
}

/// Found by the `config_file` fuzz target (fuzz/corpus/config_file/regression-sample-point-
/// no-split-fits): 210 kbit/s sampled at 57.5 % chose a bit no split of which samples that
/// early, with phase segments of 0 quanta, and `config show` overflowed turning it into
/// registers (in a release build: wrong registers).
#[test]
fn a_sample_point_only_some_bit_lengths_reach_gets_a_timing_that_reaches_it() {
    let sets = ["controller.bitrate=210000", "controller.sample_point=57.5%"]
        .map(str::to_string)
        .to_vec();
    let loaded = load_text(None, &|_| None, &sets).unwrap();
    let shown = render_show(&loaded);
    let line = shown
        .lines()
        .find(|l| l.contains("bit timing:"))
        .expect(&shown);
    // No bit of 8 MHz / 210 kbit/s ≈ 38 quanta samples as early as 57.5 % (phase segment 2 is
    // at most 8 quanta): a shorter bit within 5 % of the rate is chosen.
    let number_before = |end: &str| -> f64 {
        let head = &line[..line.find(end).expect(line)];
        head.rsplit(' ').next().unwrap().parse().expect(line)
    };
    let bitrate = number_before(" bit/s");
    assert!((199_500.0..=220_500.0).contains(&bitrate), "{line}");
    assert!(number_before(" %)") <= 57.5, "{line}");
}
