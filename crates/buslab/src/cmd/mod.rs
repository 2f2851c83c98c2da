//! One module per subcommand.

pub mod bus;
pub mod busopt;
pub mod cpu196;
pub mod dump;
pub mod r#gen;
pub mod lab;
pub mod log;
pub mod play;
pub mod regs;
pub mod send;
pub mod sim;
pub mod status;
pub mod wire;
pub mod zelle;
