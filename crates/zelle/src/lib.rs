//! ZELLE measurement cell: sans-IO device model, protocol and host client.
