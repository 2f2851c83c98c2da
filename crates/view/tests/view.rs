//! The bus view as its consumers use it: frames and statuses in, deltas out, explicit time.

use std::time::Duration;

use buslab_canbus::{
    BusState, BusSummary, ErrorRegisters, Message, NodeCounters, NodeStatus, Status,
};
use buslab_view::{BusView, Cursor, LogFilter, ViewConfig};

fn ms(n: u64) -> Duration {
    Duration::from_millis(n)
}

fn msg(t: f64, text: &str) -> Message {
    Message::rx(t, "vcan0", text.parse().unwrap())
}

fn status(number: u32, name: &str, tec: u8, state: BusState) -> NodeStatus {
    NodeStatus {
        number,
        name: name.into(),
        state,
        errors: Some(ErrorRegisters {
            alc: None,
            ecc: Some(buslab_canbus::Ecc(0x0A)),
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
    view.frame(ms(0), &msg(10.000, "123#0011"));
    view.frame(ms(10), &msg(10.010, "123#0012"));
    view.frame(ms(20), &msg(10.020, "0C0#01"));
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
    view.frame(ms(0), &msg(0.0, "100#01"));
    view.frame(ms(1), &msg(0.001, "200#02"));
    let first = view.delta(&Cursor::start(), ms(2), &all, 100);
    assert!(first.full);
    assert_eq!((first.ids.len(), first.log.len()), (2, 2));
    let mut cursor = view.advance(ms(2));
    view.frame(ms(3), &msg(0.003, "200#03"));
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
    view.frame(ms(5), &msg(0.005, "100#04"));
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
        view.frame(ms(i), &msg(i as f64 / 1000.0, &format!("{id}#{:02X}", i)));
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
    view.frame(ms(0), &msg(0.0, "080#00"));
    let all = LogFilter::all();
    let first = view.delta(&Cursor::start(), ms(1), &all, 5);
    assert!(first.full);
    let cursor = view.advance(ms(1));
    // 25 frames while the consumer looked away: 10 still in the log, 3 given, 22 missed.
    for i in 1..=25u64 {
        view.frame(ms(1 + i), &msg(i as f64 / 1000.0, &format!("080#{i:02X}")));
    }
    let d = view.delta(&cursor, ms(30), &all, 3);
    assert!(!d.full);
    assert_eq!(d.log.len(), 3);
    assert_eq!(d.log_skipped, 22);
    // Caught up: nothing missed any more.
    let cursor = view.advance(ms(30));
    view.frame(ms(31), &msg(0.031, "080#FF"));
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
        view.frame(ms(i), &msg(i as f64 / 1000.0, "555#5555555555555555"));
    }
    view.tick(ms(1000));
    let load: Vec<_> = view.load().copied().collect();
    assert_eq!(load.len(), 1);
    assert_eq!(load[0].frames, 1000);
    let p = load[0].percent.unwrap();
    assert!((85.0..100.0).contains(&p), "{p}");
    // Without a bit rate only the frame rate is known.
    let mut blind = BusView::new(ViewConfig::default());
    blind.frame(ms(0), &msg(0.0, "001#"));
    blind.tick(ms(1000));
    assert_eq!(blind.load().next().unwrap().percent, None);
}

#[test]
fn node_history_follows_tec_and_state_and_the_bus_reports_its_own_load() {
    let mut view = BusView::new(ViewConfig::default());
    view.nodes(ms(0), vec![status(1, "engine", 0, BusState::Active)]);
    let cursor = view.advance(ms(0));
    view.nodes(ms(100), vec![status(1, "engine", 136, BusState::Passive)]);
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
    view.nodes(ms(1100), vec![status(2, "dash", 0, BusState::Active)]);
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
        view.frame(ms(0), &msg(0.0, &format!("{id}#")));
    }
    let d = view.delta(&Cursor::start(), ms(1), &LogFilter::all(), 10);
    assert_eq!((d.ids.len(), d.ids_dropped), (3, 2));
    let cursor = view.advance(ms(1));
    view.clear();
    let d = view.delta(&cursor, ms(2), &LogFilter::all(), 10);
    assert!(d.full && d.ids.is_empty() && d.log.is_empty());
}
