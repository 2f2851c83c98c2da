//! SJA1000 registers decoded into words for users: SR, ECC, ALC, the error registers, and a
//! register dump. They are bus vocabulary (`buslab-bus`); this path stays for the users of this
//! crate.

pub use buslab_bus::decode::*;
