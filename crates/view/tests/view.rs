//! The bus view as its consumers use it: frames and statuses in, deltas out, explicit time.

use std::time::Duration;

use buslab_bus::{
    BusSummary, ErrorRegisters, ErrorState, Message, NodeCounters, NodeStatus, Status, Timestamp,
};
use buslab_view::{BusView, Cursor, LogFilter, ViewConfig};

fn ms(n: u64) -> Duration {
    Duration::from_millis(n)
}

fn msg(t: f64, text: &str) -> Message {
    Message::rx(Timestamp::from_secs_f64(t), "vcan0", text.parse().unwrap()).into_record()
}

fn status(number: u32, name: &str, tec: u8, state: ErrorState) -> NodeStatus {
    NodeStatus {
        number,
        name: name.into(),
        state,
        errors: Some(ErrorRegisters {
            alc: None,
            ecc: Some(buslab_bus::Ecc(0x0A)),
            rxerr: 0,
            txerr: tec,
        }),
        sr: Some(Status(0x0C)),
        timing: None,
        counters: NodeCounters::default(),
        tx_queued: 0,
        bus: BusSummary {
            bitrate: 125_000,
            load_percent: 12.5,
            frames: 0,
            errors: 0,
        },
    }
}

#[test]
fn the_table_counts_ids_measures_periods_and_highlights_changed_bytes() {
    let mut view = BusView::new(ViewConfig::default());
    view.message(ms(0), &msg(10.000, "123#0011"));
    view.message(ms(10), &msg(10.010, "123#0012"));
    view.message(ms(20), &msg(10.020, "0C0#01"));
    let rows = view.rows(ms(30));
    assert_eq!(rows.len(), 2);
    assert_eq!((rows[0].id.as_str(), rows[0].count), ("0C0", 1));
    let r = &rows[1];
    assert_eq!(
        (r.id.as_str(), r.count, r.dlc, r.data.as_str()),
        ("123", 2, 2, "0012")
    );
    assert!((r.period_ms.unwrap() - 10.0).abs() < 1e-6);
    assert_eq!(r.changed, 0b10, "only the second byte changed");
    // The highlight lasts one second, then goes.
    assert_eq!(view.rows(ms(1_011))[1].changed, 0);
}

#[test]
fn deltas_carry_only_what_changed_and_a_missed_delta_is_made_up_next_time() {
    let mut view = BusView::new(ViewConfig::default());
    let all = LogFilter::all();
    view.message(ms(0), &msg(0.0, "100#01"));
    view.message(ms(1), &msg(0.001, "200#02"));
    let first = view.delta(&Cursor::start(), ms(2), &all, 100);
    assert!(first.full);
    assert_eq!((first.ids.len(), first.log.len()), (2, 2));
    let mut cursor = view.advance(ms(2));
    view.message(ms(3), &msg(0.003, "200#03"));
    let d = view.delta(&cursor, ms(4), &all, 100);
    assert!(!d.full);
    assert_eq!(
        d.ids.iter().map(|r| r.id.as_str()).collect::<Vec<_>>(),
        ["200"]
    );
    assert_eq!(
        d.log.iter().map(|e| e.frame.as_str()).collect::<Vec<_>>(),
        ["200#03"]
    );
    // The consumer could not take that delta: its cursor stays, and the next delta has both.
    view.message(ms(5), &msg(0.005, "100#04"));
    let d = view.delta(&cursor, ms(6), &all, 100);
    assert_eq!(d.ids.len(), 2);
    assert_eq!(d.log.len(), 2);
    cursor = view.advance(ms(6));
    // The highlight of 200's byte ends at 1.003 s: the row comes again to lose it.
    let d = view.delta(&cursor, ms(1_004), &all, 100);
    assert_eq!(
        d.ids.iter().map(|r| r.id.as_str()).collect::<Vec<_>>(),
        ["200"]
    );
    assert_eq!(d.ids[0].changed, 0);
    assert!(d.log.is_empty());
}

#[test]
fn the_log_is_bounded_filtered_and_limited_to_the_newest() {
    let mut view = BusView::new(ViewConfig {
        log_capacity: 10,
        ..ViewConfig::default()
    });
    for i in 0..25u64 {
        let id = if i % 5 == 0 { "300" } else { "080" };
        view.message(ms(i), &msg(i as f64 / 1000.0, &format!("{id}#{:02X}", i)));
    }
    let only: LogFilter = "300".parse().unwrap();
    let d = view.delta(&Cursor::start(), ms(30), &only, 100);
    // The ring kept the last 10 frames (15..24): 300 is among them at 15 and 20.
    assert_eq!(
        d.log.iter().map(|e| e.frame.as_str()).collect::<Vec<_>>(),
        ["300#0F", "300#14"]
    );
    let d = view.delta(&Cursor::start(), ms(30), &LogFilter::all(), 3);
    assert_eq!(d.log.len(), 3);
    assert_eq!(d.log_skipped, 7);
    assert_eq!(d.log[2].frame, "080#18", "the newest ones, oldest first");
    assert_eq!(view.log_tail(&only, 1)[0].frame, "300#14");
}

#[test]
fn a_consumer_behind_the_log_counts_every_frame_it_missed() {
    let mut view = BusView::new(ViewConfig {
        log_capacity: 10,
        ..ViewConfig::default()
    });
    view.message(ms(0), &msg(0.0, "080#00"));
    let all = LogFilter::all();
    let first = view.delta(&Cursor::start(), ms(1), &all, 5);
    assert!(first.full);
    let cursor = view.advance(ms(1));
    // 25 frames while the consumer looked away: 10 still in the log, 3 given, 22 missed.
    for i in 1..=25u64 {
        view.message(ms(1 + i), &msg(i as f64 / 1000.0, &format!("080#{i:02X}")));
    }
    let d = view.delta(&cursor, ms(30), &all, 3);
    assert!(!d.full);
    assert_eq!(d.log.len(), 3);
    assert_eq!(d.log_skipped, 22);
    // Caught up: nothing missed any more.
    let cursor = view.advance(ms(30));
    view.message(ms(31), &msg(0.031, "080#FF"));
    let d = view.delta(&cursor, ms(32), &all, 3);
    assert_eq!((d.log.len(), d.log_skipped), (1, 0));
}

#[test]
fn load_is_estimated_from_frame_lengths_at_a_known_bit_rate() {
    let mut view = BusView::new(ViewConfig {
        bitrate: Some(125_000),
        ..ViewConfig::default()
    });
    // 1000 frames of ~111 bits in one second at 125 kbit/s: ~89 %.
    for i in 0..1000u64 {
        view.message(ms(i), &msg(i as f64 / 1000.0, "555#5555555555555555"));
    }
    view.tick(ms(1000));
    let load: Vec<_> = view.load().copied().collect();
    assert_eq!(load.len(), 1);
    assert_eq!(load[0].frames, 1000);
    let p = load[0].percent.unwrap();
    assert!((85.0..100.0).contains(&p), "{p}");
    // Without a bit rate only the frame rate is known.
    let mut blind = BusView::new(ViewConfig::default());
    blind.message(ms(0), &msg(0.0, "001#"));
    blind.tick(ms(1000));
    assert_eq!(blind.load().next().unwrap().percent, None);
}

#[test]
fn node_history_follows_tec_and_state_and_the_bus_reports_its_own_load() {
    let mut view = BusView::new(ViewConfig::default());
    view.nodes(ms(0), vec![status(1, "engine", 0, ErrorState::Active)]);
    let cursor = view.advance(ms(0));
    view.nodes(ms(100), vec![status(1, "engine", 136, ErrorState::Passive)]);
    view.tick(ms(1000));
    let d = view.delta(&cursor, ms(1000), &LogFilter::all(), 10);
    let node = &d.nodes[0];
    assert_eq!(
        (node.name.as_str(), node.state.as_str()),
        ("engine", "error-passive")
    );
    assert_eq!(node.tec, Some(136));
    assert_eq!(node.history.len(), 1, "only the new sample");
    assert_eq!(node.history[0].state, "passive");
    assert!(node.status.as_deref().unwrap().starts_with("SR=0x0C"));
    assert_eq!(
        node.ecc.as_deref(),
        Some("0x0A bit error during transmission in data field")
    );
    assert_eq!(d.load[0].percent, Some(12.5), "the bus's own figure");
    assert_eq!(d.bitrate, Some(125_000));
    // A node that left is gone.
    view.nodes(ms(1100), vec![status(2, "dash", 0, ErrorState::Active)]);
    assert_eq!(
        view.node_statuses().map(|s| s.number).collect::<Vec<_>>(),
        [2]
    );
    // As JSON for the dashboard.
    let json = serde_json::to_string(&d).unwrap();
    assert!(json.contains("\"state\":\"error-passive\""), "{json}");
}

#[test]
fn the_table_is_bounded_and_clear_starts_over() {
    let mut view = BusView::new(ViewConfig {
        max_ids: 3,
        ..ViewConfig::default()
    });
    for id in ["001", "002", "003", "004", "005"] {
        view.message(ms(0), &msg(0.0, &format!("{id}#")));
    }
    let d = view.delta(&Cursor::start(), ms(1), &LogFilter::all(), 10);
    assert_eq!((d.ids.len(), d.ids_dropped), (3, 2));
    let cursor = view.advance(ms(1));
    view.clear();
    let d = view.delta(&cursor, ms(2), &LogFilter::all(), 10);
    assert!(d.full && d.ids.is_empty() && d.log.is_empty());
}

#[test]
fn a_terminal_gets_the_rows_it_shows_and_the_figures_of_a_delta_without_one() {
    let mut view = BusView::new(ViewConfig::default());
    for (i, id) in ["005", "001", "004", "002", "003"].iter().enumerate() {
        view.message(ms(i as u64), &msg(i as f64, &format!("{id}#AA")));
    }
    view.nodes(ms(10), vec![status(1, "engine", 136, ErrorState::Passive)]);
    view.tick(ms(1_000));
    // The page is the sorted table's rows from `skip`, at most `n`.
    let page = view.rows_page(ms(1_000), 1, 2);
    assert_eq!(page, view.rows(ms(1_000))[1..3]);
    assert_eq!(
        page.iter().map(|r| r.id.as_str()).collect::<Vec<_>>(),
        ["002", "003"]
    );
    assert!(view.rows_page(ms(1_000), 5, 2).is_empty());
    // The figures a delta carries, the same without building one.
    let d = view.delta(&Cursor::start(), ms(1_000), &LogFilter::all(), 0);
    assert_eq!(
        (view.frame_count(), view.frames_per_s()),
        (d.frames, d.frames_per_s)
    );
    assert_eq!(view.frames_per_s(), 5);
    let nodes = view.node_views();
    assert_eq!(nodes.len(), 1);
    assert_eq!(
        (
            nodes[0].name.as_str(),
            nodes[0].state.as_str(),
            nodes[0].tec
        ),
        ("engine", "error-passive", Some(136))
    );
    assert!(nodes[0].history.is_empty(), "a terminal draws no chart");
    assert_eq!(view.load().next_back(), d.load.last());
}

/// Ten minutes of a node polled every 250 ms, its TEC climbing to bus-off for 3 s near the
/// end (the seed's experiment), as `buslab lab` lives it.
fn ten_minutes_with_the_experiment() -> BusView {
    let mut view = BusView::new(ViewConfig::default());
    for i in 0..=2400u64 {
        let t = ms(250 * i);
        // The cut from 570 s to 573 s: bus-off while it lasts, then back with TEC 0.
        let (tec, state) = if (2280..2292).contains(&i) {
            (255, ErrorState::BusOff)
        } else {
            (0, ErrorState::Active)
        };
        if i == 2280 {
            view.fault(t, "cut".into(), "cut at engine".into(), Some(ms(3000)));
        }
        view.nodes(t, vec![status(1, "engine", tec, state)]);
    }
    view
}

#[test]
fn a_chart_window_gets_the_last_seconds_not_the_whole_age_of_the_view() {
    let view = ten_minutes_with_the_experiment();
    let now = ms(600_000);
    let all = LogFilter::all();
    let d = view.delta_within(&Cursor::start(), now, &all, 0, Duration::from_secs(60));
    let h = &d.nodes[0].history;
    // The one sample before the window (where the line comes from), then the window's.
    assert!(h[0].t < 540.0 && h[1].t >= 540.0, "{:?}", &h[..2]);
    assert!(h[1..].iter().all(|s| s.t >= 540.0));
    // The climb is there, with the samples around it.
    assert!(h.iter().any(|s| s.tec == 255 && s.state == "bus-off"));
    assert_eq!(h.last().unwrap().t, 600.0);
    assert!(d.load.iter().all(|l| l.t >= 540.0) && !d.load.is_empty());
    assert_eq!(d.faults.len(), 1);
    assert_eq!((d.faults[0].t, d.faults[0].until), (570.0, Some(573.0)));
    // A window that ends before the cut does not carry its mark.
    let d = view.delta_within(&Cursor::start(), now, &all, 0, Duration::from_secs(10));
    assert!(d.faults.is_empty(), "{:?}", d.faults);
    assert!(d.nodes[0].history.iter().all(|s| s.tec == 0));
}

#[test]
fn equal_samples_are_kept_as_a_run_and_the_history_spans_the_retention_time() {
    let view = ten_minutes_with_the_experiment();
    let h: Vec<_> = view.history(1).copied().collect();
    // 2401 samples in three runs (active, bus-off, active): each kept as its ends.
    assert_eq!(
        h.iter().map(|s| (s.t, s.tec)).collect::<Vec<_>>(),
        [
            (0.0, 0),
            (569.75, 0),
            (570.0, 255),
            (572.75, 255),
            (573.0, 0),
            (600.0, 0)
        ]
    );
    // Samples older than the retention time go (but the one where the line comes from).
    let mut short = BusView::new(ViewConfig {
        retention: Duration::from_secs(10),
        ..ViewConfig::default()
    });
    for i in 0..100u64 {
        let tec = (i % 2) as u8;
        short.nodes(
            ms(250 * i),
            vec![status(1, "engine", tec, ErrorState::Active)],
        );
    }
    // The last sample at 24.75 s: from 14.75 s on.
    let kept: Vec<_> = short.history(1).map(|s| s.t).collect();
    assert_eq!((kept[0], kept[1]), (14.75, 15.0), "{kept:?}");
    assert_eq!(kept.len(), 41, "{kept:?}");
}

#[test]
fn error_frames_are_logged_with_their_class_and_meaning() {
    use buslab_bus::ErrorFrame;
    let mut view = BusView::new(ViewConfig::default());
    view.message(ms(0), &msg(100.0, "123#11"));
    // Linux's SJA1000 frame for a stuff error while receiving in the data field, with the
    // counters.
    let error = ErrorFrame::decode(0x288, &[0, 0, 0x04, 0x0A, 0, 0, 0, 9]).unwrap();
    view.message(
        ms(1),
        &Message::error(Timestamp::from_secs_f64(100.001), "vcan0", error),
    );
    let d = view.delta(&Cursor::start(), ms(2), &LogFilter::all(), 10);
    assert_eq!(d.log.len(), 2);
    assert_eq!(
        (d.frames, d.error_frames),
        (1, 1),
        "an error frame is no frame"
    );
    assert_eq!(d.ids.len(), 1, "nor a row of the table");
    let e = &d.log[1];
    assert_eq!(e.frame, "20000288#0000040A00000009");
    let entry = e.error.as_ref().unwrap();
    assert_eq!(entry.class, 0x288);
    assert_eq!(
        entry.classes,
        [
            "protocol-violation{{bit-stuffing-error}{data-field}}",
            "bus-error"
        ]
    );
    assert_eq!((entry.tec, entry.rec), (Some(0), Some(9)));
    let json = serde_json::to_string(&d.log).unwrap();
    assert!(json.contains("\"classes\":[\"protocol-violation"), "{json}");
    assert!(
        !json.contains("\"error\":null"),
        "frames carry no error: {json}"
    );
    // candump's filters: IDs alone leave error frames out, #MASK takes them.
    let ids: LogFilter = "123".parse().unwrap();
    assert_eq!(view.log_tail(&ids, 10).len(), 1);
    let errors: LogFilter = "#080".parse().unwrap();
    assert_eq!(
        view.log_tail(&errors, 10)[0].frame,
        "20000288#0000040A00000009"
    );
}

#[test]
fn a_repair_ends_the_fault_marks_still_running() {
    let mut view = BusView::new(ViewConfig::default());
    let cursor = view.advance(ms(0));
    let all = LogFilter::all();
    let _ = view.delta(&cursor, ms(0), &all, 0);
    let cursor = view.advance(ms(0));
    let timed = view.fault(ms(1000), "noise".into(), "noise".into(), Some(ms(500)));
    let open = view.fault(ms(1200), "cut".into(), "cut at engine".into(), None);
    let d = view.delta(&cursor, ms(1300), &all, 0);
    assert_eq!(d.faults.len(), 2);
    assert_eq!(d.faults[1].until, None);
    let cursor = view.advance(ms(1300));
    view.repaired(ms(2000));
    let d = view.delta(&cursor, ms(2000), &all, 0);
    // The ended one stays as it was; the open one now ends at the repair, same id.
    assert_eq!(
        d.faults.iter().map(|f| (f.id, f.until)).collect::<Vec<_>>(),
        [(open, Some(2.0))]
    );
    assert_ne!(timed, open);
}

const DBC: &str = r#"
BO_ 192 Engine: 8 engine
 SG_ EngineSpeed : 7|16@0+ (1,0) [0|65535] "rpm" Vector__XXX
BO_ 645 SLIO0_Reply: 3 slio0
 SG_ Register M : 0|4@1+ (1,0) [0|8] "" ppc
 SG_ In_P7_LED m0 : 23|1@1+ (1,0) [0|1] "" ppc
 SG_ ADC m8 : 9|10@0+ (0.004887585532746823,0) [0|5] "V" ppc
VAL_ 645 Register 0 "DATA_INPUT" 8 "ADC" ;
VAL_ 645 In_P7_LED 0 "off" 1 "on" ;
"#;

fn dbc_view() -> BusView {
    BusView::new(ViewConfig {
        dbc: Some(std::sync::Arc::new(
            buslab_dbc::Database::parse(DBC).unwrap(),
        )),
        ..ViewConfig::default()
    })
}

#[test]
fn with_a_database_deltas_carry_the_messages_whose_signals_changed() {
    let mut view = dbc_view();
    let all = LogFilter::all();
    view.message(ms(0), &msg(0.0, "0C0#0FA0"));
    view.message(ms(1), &msg(0.001, "285#200080"));
    // Not in the database: in the per-ID table only.
    view.message(ms(2), &msg(0.002, "123#01"));
    let first = view.delta(&Cursor::start(), ms(3), &all, 100);
    assert_eq!(first.ids.len(), 3);
    let names: Vec<&str> = first.messages.iter().map(|m| m.name.as_str()).collect();
    assert_eq!(names, ["Engine", "SLIO0_Reply"]);
    let json: serde_json::Value = serde_json::to_value(&first.messages[1]).unwrap();
    assert_eq!(json["id"], "285");
    assert_eq!(json["signals"][0]["label"], "DATA_INPUT");
    assert_eq!(json["signals"][1]["name"], "In_P7_LED");
    assert_eq!(json["signals"][1]["label"], "on");
    let cursor = view.advance(ms(3));

    // The SLIO's ADC: the register branch changes, the pins keep what DATA_INPUT said.
    view.message(ms(10), &msg(0.010, "285#280200"));
    let d = view.delta(&cursor, ms(11), &all, 100);
    assert_eq!(d.messages.len(), 1, "only the SLIO's message changed");
    let slio = &d.messages[0];
    let shown: Vec<(String, bool, bool)> = slio
        .signals
        .iter()
        .map(|s| (s.text(), s.changed, s.active))
        .collect();
    assert_eq!(
        shown,
        [
            ("ADC".to_string(), true, true),
            ("on".to_string(), false, false),
            ("2.502 V".to_string(), false, true),
        ]
    );
    let cursor = view.advance(ms(11));
    // The highlight running out is a change too: of the Register only.
    let d = view.delta(&cursor, ms(1_011), &all, 100);
    assert_eq!(d.messages.len(), 1);
    let shown: Vec<(usize, &str, bool)> = d.messages[0]
        .signals
        .iter()
        .map(|s| (s.position, s.name.as_str(), s.changed))
        .collect();
    assert_eq!(shown, [(0, "Register", false)]);
    // A frame that changes nothing but the count: the count, no signal.
    let cursor = view.advance(ms(1_011));
    view.message(ms(1_012), &msg(1.012, "285#280200"));
    let d = view.delta(&cursor, ms(1_013), &all, 100);
    assert_eq!((d.messages[0].count, d.messages[0].signals.len()), (3, 0));
    // The other branch again: it is active, the ADC no longer.
    let cursor = view.advance(ms(1_013));
    view.message(ms(1_014), &msg(1.014, "285#200080"));
    let d = view.delta(&cursor, ms(1_015), &all, 100);
    let shown: Vec<(&str, bool)> = d.messages[0]
        .signals
        .iter()
        .map(|s| (s.name.as_str(), s.active))
        .collect();
    assert_eq!(
        shown,
        [("Register", true), ("In_P7_LED", true), ("ADC", false)]
    );
    // Remote frames carry no signals.
    let cursor = view.advance(ms(1_011));
    view.message(ms(1_020), &msg(1.020, "0C0#R"));
    assert_eq!(view.delta(&cursor, ms(1_021), &all, 100).messages, []);
    assert_eq!(view.messages_page(ms(1_021), 0, 10)[0].count, 1);
}

#[test]
fn a_signal_series_is_whole_for_a_new_consumer_then_grows() {
    let mut view = dbc_view();
    let key = view.signal("Engine.EngineSpeed").unwrap();
    assert_eq!(
        view.signal("Engine.Rpm").unwrap_err().to_string(),
        "message Engine has no signal \"Rpm\" (it has EngineSpeed)"
    );
    for k in 0..30u64 {
        // 4000 rpm for 10 frames, then 4100, then 4200: three samples.
        let rpm = 4000 + 100 * (k / 10);
        view.message(ms(k * 1000), &msg(k as f64, &format!("0C0#{rpm:04X}")));
    }
    let whole = view.series(&key, &Cursor::start(), ms(30_000), ms(60_000));
    assert!(whole.full);
    assert_eq!(whole.unit, "rpm");
    assert_eq!(
        whole.points,
        [(0.0, 4000.0), (10.0, 4100.0), (20.0, 4200.0)]
    );
    // A 15-s window starts with the value held at its start.
    let window = view.series(&key, &Cursor::start(), ms(30_000), ms(15_000));
    assert_eq!(window.points, [(10.0, 4100.0), (20.0, 4200.0)]);
    let cursor = view.advance(ms(30_000));
    view.message(ms(31_000), &msg(31.0, "0C0#1068"));
    view.message(ms(31_500), &msg(31.5, "0C0#1130"));
    let more = view.series(&key, &cursor, ms(31_500), ms(60_000));
    assert!(!more.full);
    // The same value again is no sample; a new one is.
    assert_eq!(more.points, [(31.5, 4400.0)]);
    // Cleared: the next series is whole again, and empty.
    view.clear();
    let cleared = view.series(&key, &cursor, ms(32_000), ms(60_000));
    assert!(cleared.full && cleared.points.is_empty());
    // No database, no signals.
    let plain = BusView::new(ViewConfig::default());
    assert_eq!(
        plain.signal("Engine.EngineSpeed").unwrap_err().to_string(),
        "no DBC database: start with --dbc FILE to see signals"
    );
}

#[test]
fn can_fd_frames_are_counted_logged_filtered_and_decoded_but_not_in_the_byte_table() {
    let db = r#"
BO_ 2147484304 Fd: 12 x
 SG_ Tail : 88|8@1+ (1,0) [0|255] "" Vector__XXX
"#;
    let mut view = BusView::new(ViewConfig {
        dbc: Some(std::sync::Arc::new(
            buslab_dbc::Database::parse(db).unwrap(),
        )),
        ..ViewConfig::default()
    });
    let fd = |t: f64, text: &str| Message {
        at: Timestamp::from_secs_f64(t),
        channel: "can0".into(),
        direction: None,
        record: buslab_bus::Record::Fd(text.parse().unwrap()),
    };
    let fd_text = format!("00000290##1{}2A", "00".repeat(11));
    view.message(ms(0), &fd(0.0, &fd_text));
    view.message(ms(1), &msg(0.001, "123#01"));
    assert_eq!(view.frame_count(), 2);
    let all = LogFilter::all();
    let log: Vec<String> = view
        .log_tail(&all, 10)
        .into_iter()
        .map(|e| e.frame)
        .collect();
    assert_eq!(log, [fd_text.as_str(), "123#01"]);
    let only_fd: LogFilter = "00000290:1FFFFFFF".parse().unwrap();
    assert_eq!(view.log_tail(&only_fd, 10).len(), 1);
    let messages = view.messages_page(ms(2), 0, 10);
    assert_eq!(messages[0].name, "Fd");
    assert_eq!(messages[0].signals[0].number, "42");
    // The byte table is classic CAN's: 8 columns.
    assert_eq!(view.rows(ms(2)).len(), 1);
}
