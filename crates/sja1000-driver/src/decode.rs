//! SJA1000 registers decoded into words for users: SR, ECC, ALC, the error registers, and a
//! register dump. They are bus vocabulary (`buslab-bus`); the driver returns them, so they are
//! named here too (and as `buslab_canbus::decode`).

pub use buslab_bus::decode::*;
