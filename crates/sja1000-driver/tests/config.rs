//! Configuration defaults and validation with garbage values.

use buslab_sja1000_driver::config::{ClockOut, ConfigError, InterruptEnables};
use buslab_sja1000_driver::{AcceptanceFilter, CanMode, Sja1000Config, Timing};

fn bitrate(bitrate: u32) -> Timing {
    Timing::Bitrate {
        bitrate,
        sample_point_permille: None,
    }
}

fn error(config: Sja1000Config) -> String {
    config.validate().unwrap_err().to_string()
}

#[test]
fn defaults_are_valid_and_documented_values() {
    let config = Sja1000Config::default();
    config.validate().unwrap();
    assert_eq!(config.mode, CanMode::Peli);
    assert_eq!(config.crystal_hz, 16_000_000);
    assert_eq!(config.can_clock_hz(), 8_000_000);
    assert_eq!(config.output_control, 0xDA);
    assert_eq!(config.bit_timing().unwrap().registers(), (0x07, 0x4D));
    assert_eq!(config.bit_timing().unwrap().bitrate(8_000_000), 50_000);
    assert_eq!(config.cdr(), 0x80, "PeliCAN, CLKOUT = crystal / 2");
    assert_eq!(config.interrupts.ier(), 0xFF);
    Sja1000Config::basic_can().validate().unwrap();
    assert_eq!(Sja1000Config::basic_can().cdr(), 0x00);
}

/// The facts sheet's worked examples (Linux column), through the configuration.
#[test]
fn bit_rates_give_linux_registers() {
    let cases = [
        (16_000_000, 1_000_000, (0x00, 0x14)),
        (16_000_000, 800_000, (0x00, 0x16)),
        (16_000_000, 500_000, (0x00, 0x1C)),
        (16_000_000, 250_000, (0x01, 0x1C)),
        (16_000_000, 125_000, (0x03, 0x1C)),
        (16_000_000, 100_000, (0x04, 0x1C)),
    ];
    for (crystal, rate, regs) in cases {
        let config = Sja1000Config {
            crystal_hz: crystal,
            timing: bitrate(rate),
            ..Sja1000Config::default()
        };
        let timing = config.bit_timing().unwrap();
        assert_eq!(timing.registers(), regs, "{rate} bit/s: {timing}");
        assert_eq!(timing.bitrate(config.can_clock_hz()), rate);
    }
    // The fastest crystal: 12 MHz CAN clock reaches 1 Mbit/s exactly.
    let config = Sja1000Config {
        crystal_hz: 24_000_000,
        timing: bitrate(1_000_000),
        ..Sja1000Config::default()
    };
    assert_eq!(config.bit_timing().unwrap().bitrate(12_000_000), 1_000_000);
}

#[test]
fn garbage_values_are_refused_with_what_is_allowed() {
    let base = Sja1000Config::default;
    assert_eq!(
        error(Sja1000Config {
            timing: bitrate(3_000_000),
            ..base()
        }),
        "bit rate 3000000 bit/s cannot be reached from a 8000000 Hz CAN clock within 5 %"
    );
    assert_eq!(
        error(Sja1000Config {
            timing: bitrate(0),
            ..base()
        }),
        "bit rate 0 bit/s cannot be reached from a 8000000 Hz CAN clock within 5 %"
    );
    assert_eq!(
        error(Sja1000Config {
            timing: Timing::Bitrate {
                bitrate: 500_000,
                sample_point_permille: Some(1200)
            },
            ..base()
        }),
        "sample point 1200 ‰ is out of range 500..=950"
    );
    assert_eq!(
        error(Sja1000Config {
            crystal_hz: 40_000_000,
            ..base()
        }),
        "crystal frequency 40000000 Hz is out of range 1000000..=24000000 Hz"
    );
    assert_eq!(
        error(Sja1000Config {
            crystal_hz: 0,
            ..base()
        }),
        "crystal frequency 0 Hz is out of range 1000000..=24000000 Hz"
    );
    assert_eq!(
        error(Sja1000Config {
            clock_out: ClockOut::Divider(3),
            ..base()
        }),
        "clock-out divider 3 is not available: use 1, 2, 4, 6, 8, 10, 12, 14 or off"
    );
    assert!(matches!(
        Sja1000Config {
            clock_out: ClockOut::Divider(16),
            ..base()
        }
        .validate(),
        Err(ConfigError::ClockDivider { divider: 16 })
    ));
    assert_eq!(
        error(Sja1000Config {
            output_control: 0xD9,
            ..base()
        }),
        "output control 0xD9 selects the test output mode (OCMODE = 01); use normal (10), clock (11) or bi-phase (00)"
    );
    assert_eq!(
        error(Sja1000Config {
            listen_only: true,
            self_test: true,
            ..base()
        }),
        "listen-only and self-test cannot both be on: a listen-only node never transmits"
    );
    assert_eq!(
        error(Sja1000Config {
            filter: AcceptanceFilter::Basic { code: 1, mask: 2 },
            ..base()
        }),
        "a BasicCAN 8-bit acceptance filter does not fit PeliCAN mode; use Single or Dual (or AcceptAll)"
    );
}

#[test]
fn basic_can_refuses_peli_only_settings() {
    let basic = Sja1000Config::basic_can;
    assert_eq!(
        error(Sja1000Config {
            listen_only: true,
            ..basic()
        }),
        "listen-only mode exists only in PeliCAN mode, not in BasicCAN"
    );
    assert!(
        error(Sja1000Config {
            error_warning_limit: 50,
            ..basic()
        })
        .contains("fixed at 96")
    );
    assert_eq!(
        error(Sja1000Config {
            interrupts: InterruptEnables::all(),
            ..basic()
        }),
        "the error-passive interrupt exists only in PeliCAN mode, not in BasicCAN"
    );
    assert!(
        error(Sja1000Config {
            filter: AcceptanceFilter::standard_id(0x123),
            ..basic()
        })
        .contains("use Basic { code, mask }")
    );
}

#[test]
fn clock_out_and_mode_registers() {
    let cdr = |clock_out| {
        Sja1000Config {
            clock_out,
            ..Sja1000Config::default()
        }
        .cdr()
    };
    assert_eq!(cdr(ClockOut::Off), 0x88);
    assert_eq!(cdr(ClockOut::Divider(1)), 0x87);
    assert_eq!(cdr(ClockOut::Divider(14)), 0x86);
    let mod_bits = |filter, listen_only| {
        Sja1000Config {
            filter,
            listen_only,
            ..Sja1000Config::default()
        }
        .mod_bits()
    };
    assert_eq!(mod_bits(AcceptanceFilter::AcceptAll, false), 0x08);
    let dual = AcceptanceFilter::Dual {
        code: [0; 4],
        mask: [0xFF; 4],
    };
    assert_eq!(mod_bits(dual, true), 0x02);
}
