//! What feeds a device's analog inputs: voltages as functions of the device's time
//! ([`Nanos`]), and the one spelling every buslab tool takes for them (`2.5V`,
//! `sine:1Hz:2V:2.5V`, `ramp:0V:5V:10s`, `csv:input.csv`; [`SourceSpec::parse`]).
//!
//! The ZELLE cell's 8-bit converter and the CPU196 board's 10-bit ones read the same sources;
//! each device turns volts into its own codes.
#![forbid(unsafe_code)]

mod error;
mod source;
mod spec;
mod units;

pub use buslab_can::Nanos;
pub use error::SourceError;
pub use source::{Shape, Source};
pub use spec::{SPEC_HELP, SourceSpec, parse_channel_source};
