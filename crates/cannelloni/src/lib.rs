//! cannelloni's wire format, sans-IO: SocketCAN frames over UDP (v2 packets) and over TCP (a
//! greeting, then the same per-frame records back to back), so buslab's buses join the real
//! cannelloni and python-can's `can-cannelloni` backend.
//!
//! The facts (cannelloni's README and docs):
//!
//! | part | bytes |
//! |---|---|
//! | UDP header | version (2), opcode (0 DATA, 1 ACK, 2 NACK), 8-bit sequence number, frame count (u16 big-endian) |
//! | each frame | SocketCAN ID (u32 big-endian, with the EFF 0x80000000, RTR 0x40000000 and ERR 0x20000000 flags), a length byte (bit 7: CAN FD), for FD a flags byte (BRS 0x01, ESI 0x02), the data (none for a remote frame: the length byte is its DLC) |
//! | TCP | `CANNELLONIv1` from each side, then records as above, no header |
//!
//! Everything is bounded: a datagram is at most [`MAX_DATAGRAM`] bytes and [`encode_packets`]
//! splits frames over datagrams of a chosen size; a TCP record is at most [`MAX_RECORD`] bytes,
//! so the [`StreamDecoder`] never holds more than one partial record. Bad input is a typed
//! [`DecodeError`] naming the value and what is allowed.
//!
//! ```
//! use buslab_cannelloni::{CanFrame, decode_packet, encode_packets};
//!
//! let frames = [CanFrame::Classic("123#DEAD".parse()?)];
//! let datagrams = encode_packets(7, &frames, 1472)?;
//! let packet = decode_packet(&datagrams[0])?;
//! assert_eq!((packet.seq, packet.frames.as_slice()), (7, &frames[..]));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

mod record;
mod stream;
mod udp;

pub use record::{CanFrame, MAX_RECORD, decode_record, encode_record};
pub use stream::{GREETING, StreamDecoder};
pub use udp::{HEADER_LEN, MAX_DATAGRAM, OpCode, Packet, VERSION, decode_packet, encode_packets};

/// SocketCAN's flags in the ID word.
pub const EFF_FLAG: u32 = 0x8000_0000;
pub const RTR_FLAG: u32 = 0x4000_0000;
pub const ERR_FLAG: u32 = 0x2000_0000;
/// The length byte's CAN FD bit.
pub const FD_LENGTH_FLAG: u8 = 0x80;
/// The FD flags byte: bit-rate switch, error-state indicator.
pub const FD_BRS: u8 = 0x01;
pub const FD_ESI: u8 = 0x02;

/// Why bytes from a peer are not cannelloni.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum DecodeError {
    #[error("datagram of {len} bytes: a cannelloni packet has a {HEADER_LEN}-byte header")]
    ShortHeader { len: usize },
    #[error("datagram of {len} bytes: at most {MAX_DATAGRAM} allowed")]
    TooLong { len: usize },
    #[error("version {version}: only cannelloni's version {VERSION} is spoken")]
    Version { version: u8 },
    #[error("opcode {opcode}: expected 0 (DATA), 1 (ACK) or 2 (NACK)")]
    OpCode { opcode: u8 },
    #[error("the packet says {count} frames but ends after {decoded}")]
    Truncated { count: u16, decoded: u16 },
    #[error("{extra} bytes after the packet's {count} frames")]
    Trailing { count: u16, extra: usize },
    #[error("frame length {len}: a classic frame has 0..8 bytes")]
    ClassicLength { len: u8 },
    #[error("frame length {len}: a CAN FD frame has 0..8, 12, 16, 20, 24, 32, 48 or 64 bytes")]
    FdLength { len: u8 },
    #[error("ID {id:#010X}: a standard ID is at most 0x7FF and unused bits must be 0")]
    Id { id: u32 },
    #[error("a remote frame flagged CAN FD (ID word {id:#010X}): FD has no remote frames")]
    FdRemote { id: u32 },
    #[error("greeting {got:?}: expected \"CANNELLONIv1\"")]
    Greeting { got: String },
}

/// Why frames cannot be put in packets.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum EncodeError {
    #[error(
        "datagram size {size}: must leave room for the header and one CAN FD frame ({min}..={MAX_DATAGRAM})"
    )]
    DatagramSize { size: usize, min: usize },
}
