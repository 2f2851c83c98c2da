//! One module per subcommand.

pub mod cpu196;
pub mod lab;
pub mod sim;
pub mod wire;
pub mod zelle;
