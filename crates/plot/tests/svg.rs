//! Figures drawn, then read back from the SVG as a person would: by caption, legend name,
//! axis titles and tick labels.

use buslab_plot::inspect::parse;
use buslab_plot::{Band, Figure, Lane, Panel, PlotError, Series, Shade, StateLanes};

fn sine(name: &str, seconds: f64, n: usize, mid: f64, amp: f64) -> Series {
    Series::from_points(
        name,
        (0..n).map(|i| {
            let t = seconds * i as f64 / (n - 1) as f64;
            (t, mid + amp * (t * 2.0 * std::f64::consts::PI).sin())
        }),
    )
}

fn span(points: &[(f64, f64)]) -> (f64, f64) {
    points.iter().fold((f64::MAX, f64::MIN), |(lo, hi), p| {
        (lo.min(p.1), hi.max(p.1))
    })
}

#[test]
fn a_series_reads_back_with_its_range_legend_and_units() {
    let mut f = Figure::new("channels");
    let mut p = Panel::new("ZELLE", "voltage", Some("V"));
    p.series.push(sine("ch1", 3.0, 301, 2.5, 2.0));
    p.series.push(Series::from_points(
        "ch2",
        (0..301).map(|i| (i as f64 * 0.01, 1.0)),
    ));
    p.covers = Some((0.0, 5.0));
    f.panels.push(p);
    let svg = f.to_svg().unwrap();
    let seen = parse(&svg).unwrap();
    let panel = seen.panel("ZELLE").unwrap();
    assert_eq!(panel.legend(), ["ch1", "ch2"]);
    assert_eq!(panel.value_title(), Some("voltage (V)"));
    assert_eq!(panel.time_title(), Some("time (s)"));
    let ch1 = panel.series("ch1").unwrap();
    let (lo, hi) = span(&ch1);
    // 0.5..4.5 V, read to a pixel (5 V over ~170 px).
    assert!(
        (lo - 0.5).abs() < 0.06 && (hi - 4.5).abs() < 0.06,
        "{lo}..{hi}"
    );
    let (t0, t1) = (ch1[0].0, ch1[ch1.len() - 1].0);
    assert!(t0.abs() < 0.02 && (t1 - 3.0).abs() < 0.02, "{t0}..{t1}");
    let (lo, hi) = span(&panel.series("ch2").unwrap());
    assert!(
        (lo - 1.0).abs() < 0.06 && (hi - 1.0).abs() < 0.06,
        "{lo}..{hi}"
    );
}

#[test]
fn the_time_axis_unit_follows_the_span() {
    let mut f = Figure::new("short");
    let mut p = Panel::new("fast", "voltage", Some("V"));
    p.series.push(sine("ch1", 0.05, 51, 2.5, 2.0));
    f.panels.push(p);
    let seen = parse(&f.to_svg().unwrap()).unwrap();
    let panel = seen.panel("fast").unwrap();
    assert_eq!(panel.time_title(), Some("time (ms)"));
    let ch1 = panel.series("ch1").unwrap();
    // Read in ms.
    assert!(
        (ch1[ch1.len() - 1].0 - 50.0).abs() < 0.5,
        "{:?}",
        ch1.last()
    );
}

#[test]
fn bands_and_lanes_are_drawn_where_they_are() {
    let mut f = Figure::new("confinement");
    let mut p = Panel::new("TEC", "TEC", None);
    p.series.push(Series::from_points(
        "sender",
        [
            (0.0, 0.0),
            (0.1, 0.0),
            (0.2, 256.0),
            (0.3, 256.0),
            (0.4, 0.0),
            (1.0, 0.0),
        ],
    ));
    p.bands
        .push(Band::new(128.0, 256.0, "error-passive", Shade::Warning));
    p.bands
        .push(Band::new(256.0, f64::INFINITY, "bus-off", Shade::Danger));
    p.covers = Some((0.0, 280.0));
    f.panels.push(p);
    f.time_bands
        .push(Band::new(0.1, 0.3, "wire cut", Shade::Event));
    let mut sender = Lane::new("sender");
    sender.enter(0.0, 0);
    sender.enter(0.15, 1);
    sender.enter(0.2, 2);
    sender.enter(0.4, 0);
    sender.end(1.0);
    let mut pc = Lane::new("pc");
    pc.enter(0.0, 0);
    pc.end(1.0);
    f.lanes = Some(StateLanes {
        caption: "state".into(),
        states: vec![
            ("error-active".into(), Shade::Good),
            ("error-passive".into(), Shade::Warning),
            ("bus-off".into(), Shade::Danger),
        ],
        lanes: vec![sender, pc],
    });
    let seen = parse(&f.to_svg().unwrap()).unwrap();
    let tec = seen.panel("TEC").unwrap();
    assert_eq!(
        tec.legend(),
        ["error-passive", "bus-off", "wire cut", "sender"]
    );
    let passive = tec.areas("error-passive").unwrap();
    assert_eq!(passive.len(), 1);
    assert!(
        (passive[0].2 - 128.0).abs() < 2.0 && (passive[0].3 - 256.0).abs() < 2.0,
        "{passive:?}"
    );
    let cut = tec.areas("wire cut").unwrap();
    assert!(
        (cut[0].0 - 100.0).abs() < 2.0 && (cut[0].1 - 300.0).abs() < 2.0,
        "{cut:?}"
    );
    let lanes = seen.panel("state").unwrap();
    assert_eq!(lanes.legend(), ["error-active", "error-passive", "bus-off"]);
    let off = lanes.lane_spans("sender", "bus-off").unwrap();
    assert_eq!(off.len(), 1, "{off:?}");
    assert!(
        (off[0].0 - 200.0).abs() < 2.0 && (off[0].1 - 400.0).abs() < 2.0,
        "{off:?}"
    );
    assert!(lanes.lane_spans("pc", "bus-off").unwrap().is_empty());
    assert_eq!(lanes.lane_spans("pc", "error-active").unwrap().len(), 1);
}

#[test]
fn an_empty_figure_is_refused_and_an_empty_series_is_named() {
    let mut f = Figure::new("nothing");
    f.panels.push(Panel::new("load", "bus load", Some("%")));
    f.panels[0].series.push(Series::new("can0"));
    match f.to_svg() {
        Err(PlotError::NoData(why)) => assert!(why.contains("nothing"), "{why}"),
        other => panic!("{other:?}"),
    }
    f.panels[0]
        .series
        .push(Series::from_points("can1", [(0.0, 1.0), (1.0, 2.0)]));
    let seen = parse(&f.to_svg().unwrap()).unwrap();
    assert_eq!(
        seen.panel("load").unwrap().legend(),
        ["can0 (no data)", "can1"]
    );
    assert!(matches!(Figure::new("x").to_svg(), Err(PlotError::NoPanel)));
}

#[test]
fn non_finite_points_are_counted_not_drawn() {
    let mut s = Series::new("x");
    s.push(0.0, f64::NAN);
    s.push(f64::INFINITY, 1.0);
    s.push(1.0, 1.0);
    assert_eq!(s.points(), [(1.0, 1.0)]);
    assert_eq!(s.skipped(), 2);
}

#[test]
fn a_long_series_stays_small_and_keeps_its_peaks() {
    let mut s = Series::new("noise");
    for i in 0..1_000_000u32 {
        s.push(
            f64::from(i) * 1e-3,
            if i == 777_777 { 9.0 } else { f64::from(i % 7) },
        );
    }
    assert!(
        s.points().len() <= buslab_plot::MAX_POINTS,
        "{}",
        s.points().len()
    );
    let mut f = Figure::new("long");
    let mut p = Panel::new("noise", "value", None);
    p.series.push(s);
    f.panels.push(p);
    let svg = f.to_svg().unwrap();
    assert!(svg.len() < 200_000, "{} bytes", svg.len());
    let seen = parse(&svg).unwrap();
    let points = seen.panel("noise").unwrap().series("noise").unwrap();
    let (lo, hi) = span(&points);
    assert!(lo.abs() < 0.1 && (hi - 9.0).abs() < 0.1, "{lo}..{hi}");
}
