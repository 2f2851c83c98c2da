//! Block reads and writes (a driver's copy of the receive window and of the transmit buffer)
//! act exactly as the same reads and writes one register at a time, wherever they fall.

mod support;

use buslab_sja1000::Sja1000;
use proptest::prelude::*;

const MOD: u8 = 0;
const CMR: u8 = 1;
const IER: u8 = 4;
const RBSA: u8 = 30;
const CDR: u8 = 31;
const FIFO_RAM: u8 = 32;

#[derive(Clone, Debug)]
struct Setup {
    peli: bool,
    operating: bool,
    /// A transmission requested (TBS = 0) before the block access.
    pending: bool,
    ram: Vec<u8>,
    rbsa: u8,
}

fn setup() -> impl Strategy<Value = Setup> {
    (
        any::<bool>(),
        any::<bool>(),
        any::<bool>(),
        proptest::collection::vec(any::<u8>(), 64),
        0u8..64,
    )
        .prop_map(|(peli, operating, pending, ram, rbsa)| Setup {
            peli,
            operating,
            pending,
            ram,
            rbsa,
        })
}

/// A chip whose FIFO RAM holds `ram` from RBSA `rbsa` (written in PeliCAN reset mode), in the
/// mode and state `setup` asks for.
fn chip(setup: &Setup) -> Sja1000 {
    let mut chip = Sja1000::new();
    chip.write(CDR, 0x80);
    for (k, &byte) in setup.ram.iter().enumerate() {
        chip.write(FIFO_RAM + k as u8, byte);
    }
    chip.write(RBSA, setup.rbsa);
    chip.write(IER, 0xFF);
    if !setup.peli {
        chip.write(CDR, 0x00);
    }
    if setup.operating {
        chip.write(MOD, 0x00);
        if setup.pending {
            chip.write(CMR, 0x01);
        }
    }
    chip
}

/// Every register as a side-effect-free read shows it.
fn dump(chip: &Sja1000) -> Vec<u8> {
    (0..=255).map(|addr| chip.peek(addr)).collect()
}

proptest! {
    #[test]
    fn a_block_read_is_the_reads_one_by_one(setup in setup(), addr in 0u8..40, len in 0usize..16) {
        let (mut block, mut single) = (chip(&setup), chip(&setup));
        let mut got = vec![0u8; len];
        block.read_block(addr, &mut got);
        let expected: Vec<u8> = (0..len).map(|k| single.read(addr + k as u8)).collect();
        prop_assert_eq!(got, expected);
        prop_assert_eq!(dump(&block), dump(&single));
    }

    #[test]
    fn a_block_write_is_the_writes_one_by_one(
        setup in setup(),
        addr in 0u8..40,
        bytes in proptest::collection::vec(any::<u8>(), 0..16),
    ) {
        let (mut block, mut single) = (chip(&setup), chip(&setup));
        block.write_block(addr, &bytes);
        for (k, &byte) in bytes.iter().enumerate() {
            single.write(addr + k as u8, byte);
        }
        prop_assert_eq!(dump(&block), dump(&single));
    }
}

mod received_frame {
    //! The frame a chip hands a driver for the receive window is the one its bytes decode to,
    //! whatever happened to the FIFO before (frames stored and released, overruns, reset mode
    //! with RBSA and FIFO RAM rewritten).

    use super::*;
    use buslab_can::{Frame, Id};
    use buslab_sja1000::{CanMode, layout};

    use crate::support::{Bus, load_tx};

    const SR: u8 = 2;
    const SR_RBS: u8 = 0x01;
    const SR_TBS: u8 = 0x04;
    const AMR_BASIC: u8 = 5;

    #[derive(Clone, Debug)]
    enum Action {
        /// The other chip sends the frame; the chip under test receives it.
        Receive(Frame),
        /// RRB.
        Release,
        /// Reset mode, RBSA and one FIFO RAM byte rewritten, operating mode again.
        Reset { rbsa: u8, ram_at: u8, ram: u8 },
    }

    fn frame() -> impl Strategy<Value = Frame> {
        (
            prop_oneof![
                (0u16..0x800).prop_map(|id| Id::standard(id).unwrap()),
                (0u32..0x2000_0000).prop_map(|id| Id::extended(id).unwrap()),
            ],
            proptest::collection::vec(any::<u8>(), 0..=8),
            any::<bool>(),
        )
            .prop_map(|(id, data, remote)| {
                if remote {
                    Frame::remote(id, data.len() as u8).unwrap()
                } else {
                    Frame::data(id, &data).unwrap()
                }
            })
    }

    fn action() -> impl Strategy<Value = Action> {
        prop_oneof![
            4 => frame().prop_map(Action::Receive),
            2 => Just(Action::Release),
            1 => (0u8..64, 0u8..64, any::<u8>())
                .prop_map(|(rbsa, ram_at, ram)| Action::Reset { rbsa, ram_at, ram }),
        ]
    }

    /// A PeliCAN sender and the chip under test in `mode`, both accepting everything.
    fn bus(mode: CanMode) -> Bus {
        let mut sender = Sja1000::new();
        sender.write(CDR, 0x80);
        sender.write(MOD, 0x00);
        let mut receiver = Sja1000::new();
        match mode {
            CanMode::Peli => {
                receiver.write(CDR, 0x80);
                receiver.write(MOD, 0x00);
            }
            CanMode::Basic => {
                receiver.write(AMR_BASIC, 0xFF);
                receiver.write(MOD, 0x00);
            }
        }
        Bus::new(vec![sender, receiver])
    }

    fn reset(chip: &mut Sja1000, rbsa: u8, ram_at: u8, ram: u8) {
        let peli = chip.mode() == CanMode::Peli;
        chip.write(MOD, 0x01);
        if !peli {
            chip.write(CDR, 0x80); // RBSA and the FIFO RAM are PeliCAN registers
        }
        chip.write(RBSA, rbsa);
        chip.write(FIFO_RAM + ram_at, ram);
        if !peli {
            chip.write(CDR, 0x00);
            chip.write(AMR_BASIC, 0xFF);
        }
        chip.write(MOD, 0x00);
    }

    /// The window's message decoded from its bytes, as a driver without the shortcut reads it.
    fn decoded(chip: &Sja1000) -> Frame {
        let (mode, base) = match chip.mode() {
            CanMode::Peli => (CanMode::Peli, 16),
            CanMode::Basic => (CanMode::Basic, 20),
        };
        let mut buf = [0u8; 13];
        for (k, byte) in buf.iter_mut().enumerate() {
            *byte = chip.peek(base + k as u8);
        }
        let len = layout::stored_len(mode, buf[0], buf[1]);
        buf[len..].fill(0);
        layout::decode_tx(mode, &buf)
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        #[test]
        fn is_the_frame_its_bytes_decode_to(
            peli in any::<bool>(),
            actions in proptest::collection::vec(action(), 1..40),
        ) {
            let mode = if peli { CanMode::Peli } else { CanMode::Basic };
            let base = if peli { 16 } else { 20 };
            let other = if peli { CanMode::Basic } else { CanMode::Peli };
            let mut bus = bus(mode);
            for action in actions {
                match action {
                    Action::Receive(frame) => {
                        load_tx(&mut bus.chips[0], &frame.to_string());
                        bus.chips[0].write(CMR, 0x01);
                        bus.run_until(400, "the frame sent", |bus| {
                            bus.chips[0].peek(SR) & SR_TBS != 0
                        });
                        bus.run(3);
                    }
                    Action::Release => bus.chips[1].write(CMR, 0x04),
                    Action::Reset { rbsa, ram_at, ram } => {
                        reset(&mut bus.chips[1], rbsa, ram_at, ram)
                    }
                }
                let chip = &bus.chips[1];
                let holds_one = chip.peek(SR) & SR_RBS != 0;
                let given = chip.received_frame(mode, base);
                prop_assert_eq!(given.is_some(), holds_one, "a frame while the FIFO holds one");
                if let Some(frame) = given {
                    prop_assert_eq!(frame, decoded(chip));
                }
                prop_assert_eq!(chip.received_frame(other, base), None, "another layout");
                prop_assert_eq!(chip.received_frame(mode, base + 1), None, "another address");
            }
        }
    }
}
