//! A fixed amount of `--speed max` work for instruction counting: 1 sender kept busy and N
//! receivers (8 unless told) on a 1 Mbit/s bus for a given number of bit-times, every frame
//! carrying a new sequence number (as real traffic does), deliveries taken. Prints the frames
//! carried and the deliveries, so that a profiler's instruction counts divide into
//! instructions per frame and per receiver. A receiver's own cost is the difference between
//! two runs that differ only in the number of receivers (same bit-times: same frames),
//! divided by the extra deliveries:
//!
//! ```text
//! cargo build --release -p buslab-vbus --example vbus_frame_cost
//! for n in 1 8; do valgrind --tool=callgrind --callgrind-out-file=cg.$n \
//!     target/release/examples/vbus_frame_cost 2000000 $n; done
//! # per receiver and frame, whole program:
//! #   (Ir(cg.8) - Ir(cg.1)) / (deliveries(8) - deliveries(1))
//! # the client node alone: the same with the inclusive Ir of
//! # `<buslab_canbus::node::Sja1000Node as buslab_can::node::BusNode>::count_frame`
//! # and `…::advance_frame` (callgrind_annotate --inclusive=yes).
//! ```

use buslab_can::BitTime;
use buslab_can::{Frame, Id};
use buslab_vbus::VirtualBus;

const BITRATE: u32 = 1_000_000;
const DEFAULT_RECEIVERS: usize = 8;
const DEFAULT_BITS: u64 = 2_000_000;
// The longest classic frame with its stuff bits and intermission: as the server's
// `--speed max` loop, each stretch runs long enough for the queued frames to end inside it
// (a frame cut by a stretch's end would be stepped bit by bit).
use buslab_can::wire::LONGEST_FRAME_BITS;

/// `[BIT_TIMES [RECEIVERS]]`, or what is wrong with them.
fn arguments() -> Result<(u64, usize), String> {
    let mut args = std::env::args().skip(1);
    let bits = match args.next() {
        None => DEFAULT_BITS,
        Some(arg) => arg
            .parse::<u64>()
            .ok()
            .filter(|&bits| bits > 0)
            .ok_or(format!("bit-times {arg:?}: a whole number above 0"))?,
    };
    let most = buslab_vbus::MAX_NODES - 1;
    let receivers = match args.next() {
        None => DEFAULT_RECEIVERS,
        Some(arg) => arg
            .parse::<usize>()
            .ok()
            .filter(|n| (1..=most).contains(n))
            .ok_or(format!(
                "receivers {arg:?}: 1 to {most} (a frame needs a receiver to acknowledge it)"
            ))?,
    };
    match args.next() {
        Some(extra) => Err(format!("{extra:?}: only BIT_TIMES and RECEIVERS are taken")),
        None => Ok((bits, receivers)),
    }
}

fn main() -> std::process::ExitCode {
    let (bits, receivers) = match arguments() {
        Ok(args) => args,
        Err(error) => {
            eprintln!("vbus_frame_cost: {error}; usage: vbus_frame_cost [BIT_TIMES [RECEIVERS]]");
            return std::process::ExitCode::from(2);
        }
    };
    let mut bus = VirtualBus::new(BITRATE).expect("1 Mbit/s is a valid bit rate");
    let sender = bus.join().expect("room for the sender");
    for _ in 0..receivers {
        bus.join().expect("room for a receiver");
    }
    let id = Id::standard(0x123).expect("11 bits");
    let mut sequence = 0u64;
    let mut delivered = 0usize;
    let end = bus.now() + BitTime::new(bits);
    while bus.now() < end {
        let node = bus.client_mut(sender).expect("the sender joined");
        while node.tx_room() > 0 {
            let frame = Frame::data(id, &sequence.to_le_bytes()).expect("8 bytes");
            node.submit(frame).expect("room checked");
            sequence += 1;
        }
        let queued = bus
            .client_mut(sender)
            .expect("the sender joined")
            .tx_queued() as u64;
        bus.run_until(BitTime::new(
            ((bus.now() + BitTime::new((queued + 1) * LONGEST_FRAME_BITS)).min(end)).get(),
        ));
        for (_, node) in bus.clients_mut() {
            delivered += node.take_deliveries().count();
        }
    }
    let frames = bus.stats().frames;
    println!("receivers {receivers} bit-times {bits} frames {frames} deliveries {delivered}");
    std::process::ExitCode::SUCCESS
}
