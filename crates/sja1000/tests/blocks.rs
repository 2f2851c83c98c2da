//! Block reads and writes (a driver's copy of the receive window and of the transmit buffer)
//! act exactly as the same reads and writes one register at a time, wherever they fall.

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
