//! Properties over arbitrary input: the reset always works, nothing panics or hangs.

use std::collections::VecDeque;
use std::io;
use std::time::Duration;

use buslab_device::Nanos;
use buslab_zelle::client::{Client, Port, SeriesParams, Transfer};
use buslab_zelle::timing::MS;
use buslab_zelle::{Activity, Cell};
use proptest::prelude::*;

/// A byte, and how long the host waited before sending it (0 = back to back).
fn garbage() -> impl Strategy<Value = Vec<(u8, u16)>> {
    // Bias toward command bytes and zeros so the exchanges are actually entered.
    let byte = prop_oneof![0u8..=20, any::<u8>(), Just(0u8), Just(1u8), Just(9u8)];
    prop::collection::vec((byte, prop_oneof![Just(0u16), 0u16..3000]), 0..80)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    #[test]
    fn ten_zeros_bring_any_state_back_to_ready(bytes in garbage()) {
        let mut c = Client::new(Cell::default().into_sim_port());
        for (b, gap_us) in bytes {
            c.port().pause(Duration::from_micros(u64::from(gap_us)));
            c.port().send(&[b]).unwrap();
        }
        c.reset().unwrap();
        prop_assert_eq!(c.port().device().activity(), Activity::Ready);
        // And it answers commands.
        prop_assert_eq!(c.key_pressed().unwrap(), false);
        prop_assert_eq!(c.peek(0x0000).unwrap(), c.port().device().ram().read(0));
    }

    #[test]
    fn the_model_survives_anything(
        events in prop::collection::vec((0u8..8, any::<u8>(), 0u32..5_000_000), 0..200)
    ) {
        let mut cell = Cell::default();
        let mut t = Nanos::ZERO;
        let mut out = Vec::new();
        for (kind, byte, dt) in events {
            t += Nanos::new(u64::from(dt));
            match kind {
                0..=3 => cell.receive(t, byte),
                4 => cell.poll(t, &mut out),
                5 => cell.press_key_for(t, u64::from(byte) * 30 * MS),
                6 if byte & 1 == 0 => cell.power_off(t),
                6 => cell.power_on(t),
                _ => cell.reset(t),
            }
            // After a poll every deadline lies ahead, so a pacer always makes progress.
            if kind == 4 && let Some(d) = cell.next_deadline() {
                prop_assert!(d > t, "deadline {} at {}", d, t);
            }
        }
        cell.poll(t + 60_000 * MS, &mut out);
    }

    #[test]
    fn the_client_survives_garbage_replies(replies in prop::collection::vec(any::<u8>(), 0..64)) {
        let mut c = Client::new(GarbagePort { replies: replies.into(), now: Duration::ZERO });
        // Each call either succeeds or fails cleanly; none panics or waits forever.
        let _ = c.key_pressed();
        let _ = c.read_p26();
        let _ = c.analog(1);
        let _ = c.analog_repeat(&[1, 2, 3]);
        let _ = c.read_data(20, Transfer::Pipelined);
        let _ = c.write_data(&[1, 2, 3], Transfer::Pipelined);
        let _ = c.load_program(&[1, 2, 3], Transfer::StopAndWait);
        let _ = c.value_count();
        let _ = c.measure(&SeriesParams::new(&[1], 2, 5).unwrap(), 1, |_| {});
        let _ = c.reset();
    }
}

/// A case the property found: command 6 starts the (empty) program area, and "Inter" came to
/// wait for a byte still on the line just as the core reached the cell's time less its lag.
/// It took reaching that target for reaching the end of the wait, looked again, waited again:
/// the cell never returned from the host's pause.
#[test]
fn inter_waiting_past_the_cores_target_does_not_hang() {
    let bytes: [(u8, u16); 44] = [
        (1, 0),
        (0, 0),
        (1, 2371),
        (9, 768),
        (17, 577),
        (1, 0),
        (0, 2677),
        (11, 0),
        (1, 2526),
        (14, 0),
        (0, 2295),
        (9, 0),
        (89, 2183),
        (9, 0),
        (1, 1361),
        (0, 0),
        (9, 0),
        (9, 0),
        (0, 0),
        (214, 1132),
        (1, 0),
        (10, 0),
        (0, 0),
        (8, 2174),
        (7, 0),
        (1, 2290),
        (9, 0),
        (1, 0),
        (1, 0),
        (9, 0),
        (11, 0),
        (9, 2653),
        (0, 2988),
        (6, 1932),
        (0, 64),
        (123, 0),
        (196, 2261),
        (1, 0),
        (1, 2143),
        (185, 2930),
        (202, 0),
        (0, 1143),
        (15, 1755),
        (25, 1881),
    ];
    let mut c = Client::new(Cell::default().into_sim_port());
    for (b, gap_us) in bytes {
        c.port().pause(Duration::from_micros(u64::from(gap_us)));
        c.port().send(&[b]).unwrap();
    }
    c.reset().unwrap();
    assert_eq!(c.port().device().activity(), Activity::Ready);
}

/// Answers with whatever it was given, a few bytes at a time, then times out.
struct GarbagePort {
    replies: VecDeque<u8>,
    now: Duration,
}

impl Port for GarbagePort {
    fn send(&mut self, _: &[u8]) -> io::Result<()> {
        Ok(())
    }
    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        let n = buf.len().min(self.replies.len()).min(3);
        if n == 0 {
            self.now += timeout;
        }
        for (slot, b) in buf.iter_mut().zip(self.replies.drain(..n)) {
            *slot = b;
        }
        Ok(n)
    }
    fn now(&self) -> Duration {
        self.now
    }
    fn pause(&mut self, d: Duration) {
        self.now += d;
    }
    fn drain(&mut self) -> io::Result<()> {
        Ok(())
    }
    fn discard_input(&mut self) -> io::Result<()> {
        self.replies.clear();
        Ok(())
    }
}
