//! MoniCAN (`buslab_monican::MoniCan`, `buslab monican` and the PowerPC node): keys from a
//! terminal (any bytes, escape sequences, Ctrl keys) and frames from the bus (SLIO replies,
//! sign-ons, a supervisor's mail notifier and message on any ID, remote frames), over time.
//! No panic, and nothing grows without bound: the frames it queues, the terminal output, the
//! deadlines (never stuck in the past).
#![no_main]

use buslab_can::{Frame, Id, Nanos, StandardId};
use buslab_monican::{Config, DEFAULT_MAIL_ID, MoniCan};
use buslab_slio::SlioId;
use libfuzzer_sys::arbitrary::{Result, Unstructured};
use libfuzzer_sys::fuzz_target;

/// Frames MoniCAN may have queued: the 48 calibration frames, a request per SLIO and input
/// kind, mail answers; far below this unless something leaks.
const MAX_QUEUED: usize = 1_000;
/// One full redraw of a 24 × 80 VT100 screen with attributes is a few kB.
const MAX_SCREEN: usize = 64 * 1024;

fn frame_id(u: &mut Unstructured) -> Result<Id> {
    let raw = match u.int_in_range(0..=3u8)? {
        0 => SlioId::new(u.int_in_range(0..=15)?)
            .unwrap()
            .reply_id()
            .as_raw() as u16,
        1 => SlioId::new(u.int_in_range(0..=15)?)
            .unwrap()
            .command_id()
            .as_raw() as u16,
        2 => *u.choose(&[DEFAULT_MAIL_ID, 0])?,
        _ => u.int_in_range(0..=0x7FF)?,
    };
    Ok(Id::Standard(StandardId::new(raw).unwrap()))
}

fn run(u: &mut Unstructured) -> Result<()> {
    let mut now = Nanos::ZERO;
    let mut app = MoniCan::new(Config::default(), now).unwrap();
    let check = |app: &mut MoniCan, now: Nanos| {
        while app.poll_event().is_some() {}
        assert!(app.queued() <= MAX_QUEUED, "{} frames queued", app.queued());
        let screen = app.take_screen();
        assert!(
            screen.len() <= MAX_SCREEN,
            "{} bytes of screen",
            screen.len()
        );
        // A few frames sent per step, as a bus would take them.
        for _ in 0..4 {
            app.poll_transmit(now);
        }
        for _ in 0..1_000 {
            match app.next_deadline() {
                Some(t) if t <= now => app.handle_timeout(now),
                _ => return,
            }
        }
        panic!(
            "the deadline {:?} stays in the past of {now}",
            app.next_deadline()
        );
    };
    while !u.is_empty() {
        match u.int_in_range(0..=4u8)? {
            0 | 1 => {
                let n = u.int_in_range(1..=8)?.min(u.len());
                for &key in u.bytes(n)? {
                    app.handle_key(now, key);
                }
            }
            2 => {
                let id = frame_id(u)?;
                let frame = if u.ratio(1, 8)? {
                    Frame::remote(id, u.int_in_range(0..=8)?).unwrap()
                } else {
                    let len = u.int_in_range(0..=8)?;
                    Frame::data(id, u.bytes(len.min(u.len()))?).unwrap()
                };
                app.handle_frame(now, &frame);
            }
            3 => now += Nanos::from_millis(u64::from(u.int_in_range(0..=255u8)?)),
            _ => {
                if let Some(t) = app.next_deadline() {
                    now = now.max(t);
                }
            }
        }
        check(&mut app, now);
    }
    Ok(())
}

fuzz_target!(|data: &[u8]| {
    let _ = run(&mut Unstructured::new(data));
});
