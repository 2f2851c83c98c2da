//! Errors of the simulator.

/// A duration that is not `<number><unit>`.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error(
    "bad duration {text:?}: expected a number with a unit: s, ms, us, ns, or bits for bit-times (e.g. 2ms, 1000bits; a bare number only for 0)"
)]
pub struct DurationError {
    pub text: String,
}
