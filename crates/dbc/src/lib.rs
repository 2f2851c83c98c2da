//! DBC databases as a CAN engineer uses them: messages and their signals, decoded from a
//! frame's payload into physical values and encoded back, sans-IO.
//!
//! The file is parsed by the `can-dbc` crate; the model, the bit layout (Intel and Motorola
//! numbering), scaling, value tables and multiplexing (simple and extended) are written here.
//! Decoding takes a payload slice, classic or CAN FD (up to 64 bytes), so it serves frames,
//! logs and views alike.
//!
//! ```
//! use buslab_dbc::Database;
//! let db = Database::parse(r#"
//! BO_ 291 Engine: 8 ECU
//!  SG_ Speed : 0|16@1+ (0.1,0) [0|6553.5] "km/h" Vector__XXX
//! "#).unwrap();
//! let engine = db.message_by_name("Engine").unwrap();
//! let values = engine.decode(&[0x10, 0x27, 0, 0, 0, 0, 0, 0]);
//! assert_eq!(values[0].physical, 1000.0);
//! ```

mod database;
mod error;
mod layout;
mod message;
mod signal;
mod source;
pub mod text;

pub use database::Database;
pub use error::{DbcError, EncodeError};
pub use message::{Decoded, Message};
pub use signal::{ByteOrder, Multiplexing, Signal, ValueKind};
