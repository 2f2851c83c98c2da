//! The bit-level wire codec: frame → bits (unstuffed and stuffed, CRC-15) and a bit-by-bit
//! receiver that rebuilds frames and reports stuff, CRC and form errors with their position.
