//! Transports: pseudo-terminals, serial ports, pacing sans-IO byte devices to wall-clock time.
