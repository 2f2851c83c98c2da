//! Register rules of the facts sheet that need no bus traffic (one test per rule).

use buslab_sja1000::Sja1000;

const MOD: u8 = 0;
const CMR: u8 = 1;
const SR: u8 = 2;
const IR: u8 = 3;
const IER: u8 = 4;
const BTR0: u8 = 6;
const BTR1: u8 = 7;
const OCR: u8 = 8;
const EWLR: u8 = 13;
const RXERR: u8 = 14;
const TXERR: u8 = 15;
const RMC: u8 = 29;
const RBSA: u8 = 30;
const CDR: u8 = 31;

/// A chip switched to PeliCAN, still in reset mode.
fn peli() -> Sja1000 {
    let mut chip = Sja1000::new();
    chip.write(CDR, 0x80);
    chip
}

#[test]
fn hardware_reset_values() {
    let mut chip = Sja1000::new();
    assert_eq!(chip.read(0) & 0x01, 0x01, "BasicCAN CR.RR set");
    assert_eq!(chip.read(0) & 0x20, 0x20, "CR bit 5 reads 1");
    assert_eq!(chip.read(CMR), 0xFF, "BasicCAN CMR reads 0xFF");
    assert_eq!(chip.read(SR), 0x0C, "BasicCAN SR = TCS | TBS");
    assert_eq!(chip.read(IR), 0xE0, "BasicCAN IR bits 7..5 read 1");
    assert_eq!(chip.read(CDR), 0x00);

    let mut chip = peli();
    assert_eq!(chip.read(MOD), 0x01);
    assert_eq!(chip.read(CMR), 0x00, "PeliCAN CMR reads 0");
    assert_eq!(
        chip.read(SR),
        0x3C,
        "PeliCAN SR = TS | RS | TCS | TBS in reset mode"
    );
    assert_eq!(chip.read(IR), 0x00);
    assert_eq!(chip.read(EWLR), 96);
    assert_eq!((chip.read(RXERR), chip.read(TXERR)), (0, 0));
    assert_eq!((chip.read(RMC), chip.read(RBSA)), (0, 0));
}

#[test]
fn timing_output_and_limits_are_writable_only_in_reset_mode() {
    let mut chip = peli();
    chip.write(BTR0, 0x07);
    chip.write(BTR1, 0x4D);
    chip.write(OCR, 0xDA);
    chip.write(EWLR, 50);
    chip.write(TXERR, 10);
    chip.write(RXERR, 20);
    chip.write(MOD, 0x00); // operating mode
    assert!(!chip.in_reset_mode());
    chip.write(BTR0, 0xFF);
    chip.write(BTR1, 0xFF);
    chip.write(OCR, 0x00);
    chip.write(EWLR, 1);
    chip.write(TXERR, 200);
    assert_eq!(
        (
            chip.read(BTR0),
            chip.read(BTR1),
            chip.read(OCR),
            chip.read(EWLR)
        ),
        (0x07, 0x4D, 0xDA, 50)
    );
    assert_eq!(chip.bit_timing().bitrate(8_000_000), 50_000);
    assert_eq!(
        chip.read(TXERR),
        10,
        "forced counter values carry into operating mode"
    );
    assert_eq!(chip.read(RXERR), 20);
}

#[test]
fn mode_bits_change_only_in_reset_mode() {
    let mut chip = peli();
    chip.write(MOD, 0x01 | 0x02 | 0x08); // RM, LOM, AFM
    assert_eq!(chip.read(MOD), 0x0B);
    chip.write(MOD, 0x02 | 0x08); // leave reset, keep LOM/AFM
    assert_eq!(chip.read(MOD), 0x0A);
    chip.write(MOD, 0x04); // try to drop LOM/AFM and set STM while operating
    assert_eq!(
        chip.read(MOD),
        0x0A,
        "LOM/STM/AFM ignored in operating mode"
    );
}

#[test]
fn sleep_cannot_be_set_in_reset_mode() {
    let mut chip = peli();
    chip.write(MOD, 0x01 | 0x10);
    assert_eq!(chip.read(MOD) & 0x10, 0);
}

#[test]
fn can_mode_switches_only_in_reset_mode() {
    let mut chip = peli();
    chip.write(MOD, 0x00);
    chip.write(CDR, 0x07); // try to go back to BasicCAN while operating
    assert_eq!(
        chip.read(CDR),
        0x87,
        "only the clock divider bits change when operating"
    );
    assert_eq!(chip.mode(), buslab_sja1000::CanMode::Peli);
}

#[test]
fn acceptance_registers_share_the_window_with_the_frame_buffers() {
    let mut chip = peli();
    for (k, value) in [0x11, 0x22, 0x33, 0x44, 0x55, 0x66, 0x77, 0x88]
        .into_iter()
        .enumerate()
    {
        chip.write(16 + k as u8, value);
    }
    assert_eq!(chip.read(16), 0x11, "ACR0 in reset mode");
    assert_eq!(chip.read(23), 0x88, "AMR3 in reset mode");
    assert_eq!(chip.read(24), 0x00, "24..28 read 0 in reset mode");
    chip.write(MOD, 0x00);
    // Operating mode: writes go to the TX buffer (readable at 96..), reads show the RX window.
    chip.write(16, 0x08);
    assert_eq!(chip.read(96), 0x08);
    chip.write(MOD, 0x01);
    assert_eq!(chip.read(16), 0x11, "ACR0 untouched by TX buffer writes");
}

#[test]
fn rbsa_writable_in_reset_mode_and_kept_by_software_reset() {
    let mut chip = peli();
    chip.write(RBSA, 0x2A);
    chip.write(MOD, 0x00);
    chip.write(RBSA, 0x05);
    assert_eq!(chip.read(RBSA), 0x2A);
    chip.write(MOD, 0x01);
    assert_eq!(chip.read(RBSA), 0x2A);
    chip.write(RBSA, 0xFF);
    assert_eq!(chip.read(RBSA), 0x3F, "bits 7..6 read 0");
}

#[test]
fn ier_is_writable_in_both_modes() {
    let mut chip = peli();
    chip.write(IER, 0x0F);
    chip.write(MOD, 0x00);
    chip.write(IER, 0xFF);
    assert_eq!(chip.read(IER), 0xFF);
}

#[test]
fn basic_can_hides_configuration_in_operating_mode() {
    let mut chip = Sja1000::new();
    chip.write(4, 0xAB); // ACR
    chip.write(5, 0xCD); // AMR
    chip.write(BTR0, 0x03);
    chip.write(0, 0x00); // CR: operating
    for addr in [4, 5, BTR0, BTR1, OCR] {
        assert_eq!(
            chip.read(addr),
            0xFF,
            "address {addr} reads 0xFF when operating"
        );
    }
    chip.write(0, 0x01);
    assert_eq!(
        (chip.read(4), chip.read(5), chip.read(BTR0)),
        (0xAB, 0xCD, 0x03)
    );
}

#[test]
fn tx_buffer_is_locked_while_a_transmission_is_pending() {
    let mut chip = peli();
    chip.write(MOD, 0x00);
    chip.write(16, 0x01); // SFF, DLC 1
    chip.write(17, 0x24);
    chip.write(18, 0x60);
    chip.write(19, 0xAA);
    chip.write(CMR, 0x01); // TR
    assert_eq!(chip.read(SR) & 0x0C, 0x00, "TBS and TCS cleared by TR");
    chip.write(19, 0x55);
    assert_eq!(
        chip.read(96 + 3),
        0xAA,
        "write to a locked TX buffer is dropped"
    );
}

#[test]
fn abort_before_the_frame_starts_releases_the_buffer_without_success() {
    let mut chip = peli();
    chip.write(IER, 0x02); // TIE
    chip.write(MOD, 0x00);
    chip.write(16, 0x00);
    chip.write(17, 0x24);
    chip.write(18, 0x60);
    chip.write(CMR, 0x01);
    chip.write(CMR, 0x02); // AT before any bus bit-time
    let sr = chip.read(SR);
    assert_eq!(sr & 0x04, 0x04, "TBS back to 1");
    assert_eq!(sr & 0x08, 0x00, "TCS stays 0: not sent");
    assert_eq!(chip.read(IR) & 0x02, 0x02, "TI raised");
    assert_eq!(chip.read(IR) & 0x02, 0x00, "reading IR cleared TI");
}
