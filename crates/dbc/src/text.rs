//! Decoded signals as people read them, in cantools' spelling: `Name(Signal: value unit, …)`
//! on one line, or one signal per line with `{:#}`. A value with a label in the value table
//! shows the label alone, as cantools 45 prints it (`Enable: Enabled`); a number keeps the integer/float distinction of the database
//! (an integer signal with an integer factor and offset prints without a decimal point).

use std::fmt;

use crate::message::{Decoded, Message};
use crate::signal::{Signal, ValueKind};

/// A signal's value as text: its label, or the number with its unit.
pub struct Value<'a> {
    pub signal: &'a Signal,
    pub decoded: Decoded,
}

impl fmt::Display for Value<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Some(label) = self.signal.choice(self.decoded.raw) {
            return f.write_str(label);
        }
        write!(f, "{}", Number::of(self.signal, self.decoded.physical))?;
        if !self.signal.unit().is_empty() {
            write!(f, " {}", self.signal.unit())?;
        }
        Ok(())
    }
}

/// A physical value as a number alone (no label, no unit): what CSV cells and plots take.
pub struct Number {
    value: f64,
    integer: bool,
}

impl Number {
    pub fn of(signal: &Signal, physical: f64) -> Self {
        let integer = matches!(signal.kind(), ValueKind::Unsigned | ValueKind::Signed)
            && signal.factor().fract() == 0.0
            && signal.offset().fract() == 0.0
            && physical.fract() == 0.0
            && physical.abs() < 2f64.powi(63);
        Self {
            value: physical,
            integer,
        }
    }
}

impl fmt::Display for Number {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.integer {
            write!(f, "{}", self.value as i64)
        } else {
            // Debug keeps the decimal point of a whole float (`3.0`), as cantools prints it.
            write!(f, "{:?}", self.value)
        }
    }
}

/// A message and the signals decoded from one frame of it.
pub struct DecodedMessage<'a> {
    pub message: &'a Message,
    pub values: &'a [Decoded],
}

impl fmt::Display for DecodedMessage<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let multiline = f.alternate();
        write!(f, "{}(", self.message.name())?;
        for (i, decoded) in self.values.iter().enumerate() {
            let signal = &self.message.signals()[decoded.signal];
            let value = Value {
                signal,
                decoded: *decoded,
            };
            if multiline {
                write!(f, "\n    {}: {value}", signal.name())?;
                if i + 1 < self.values.len() {
                    f.write_str(",")?;
                }
            } else {
                if i > 0 {
                    f.write_str(", ")?;
                }
                write!(f, "{}: {value}", signal.name())?;
            }
        }
        if multiline && !self.values.is_empty() {
            f.write_str("\n")?;
        }
        f.write_str(")")
    }
}

#[cfg(test)]
mod tests {
    use crate::Database;

    use super::*;

    const DBC: &str = r#"
BO_ 496 ExampleMessage: 8 PCM1
 SG_ Enable : 7|1@0- (1,0) [0|0] "-" Vector__XXX
 SG_ AverageRadius : 6|6@0+ (0.1,0) [0|5] "m" Vector__XXX
 SG_ Temperature : 0|12@0- (0.01,250) [229.53|270.47] "degK" Vector__XXX

VAL_ 496 Enable 0 "Disabled" -1 "Enabled" ;
"#;

    #[test]
    fn one_line_and_multi_line_as_cantools_prints_them() {
        let db = Database::parse(DBC).unwrap();
        let message = db.message_by_name("ExampleMessage").unwrap();
        let values = message.decode(&[0x80, 0x4A, 0x0F, 0, 0, 0, 0, 0]);
        let decoded = DecodedMessage {
            message,
            values: &values,
        };
        assert_eq!(
            decoded.to_string(),
            "ExampleMessage(Enable: Enabled, AverageRadius: 0.0 m, Temperature: 255.92 degK)"
        );
        assert_eq!(
            format!("{decoded:#}"),
            "ExampleMessage(\n    Enable: Enabled,\n    AverageRadius: 0.0 m,\n    Temperature: 255.92 degK\n)"
        );
    }
}
