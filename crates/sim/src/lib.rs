//! Bit-level CAN bus simulator: nodes on a wired-AND bus in virtual bit-time, fault injection, observers, VCD.
