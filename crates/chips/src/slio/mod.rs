//! Facts of the Philips P82C150 SLIO and the seed's demo board around it.

pub mod board;
pub mod ids;
pub mod registers;

pub use ids::{CALIBRATION_ID, Direction, SlioId, SlioIdError, calibration_frame};

/// The demo board's LED pins, in MoniCAN's order.
pub const LED_PINS: [u8; 5] = [7, 8, 9, 11, 12];
/// The demo board's supply: analog inputs span 0..5 V, DPM outputs swing to it.
pub const VDD: f64 = 5.0;
