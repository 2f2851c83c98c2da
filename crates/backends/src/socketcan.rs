//! Linux SocketCAN (`socketcan:IFACE`): a raw CAN socket on an interface (`can0`, `vcan0`,
//! `slcan0`), with the kernel's receive timestamps, ID filters in the kernel, and error
//! frames decoded into [`ErrorFrame`]s.
//!
//! As with candump, the socket does not receive the frames it sends itself (the kernel's
//! `CAN_RAW_RECV_OWN_MSGS` is off), but it does receive those of other programs on the same
//! interface.

use std::io;
use std::time::{Duration, UNIX_EPOCH};

use buslab_bus::bus::matches_any;
use buslab_bus::error_frame::class;
use buslab_bus::{
    BusError, CanBus, CanError, ControllerProblems, ErrorFrame, ErrorState, Filter, Message,
    Record, Timestamp,
};
use buslab_can::{Frame, Id};
use socketcan::frame::can_frame_default;
use socketcan::{CanFilter, CanFrame, CanSocket, Socket, SocketOptions};

const EFF_FLAG: u32 = libc::CAN_EFF_FLAG;
const RTR_FLAG: u32 = libc::CAN_RTR_FLAG;
const ERR_FLAG: u32 = libc::CAN_ERR_FLAG;
const EFF_MASK: u32 = libc::CAN_EFF_MASK;
const ERR_MASK: u32 = libc::CAN_ERR_MASK;

/// Error classes the bus always asks the kernel for, to know its state; they reach the user
/// only after `set_error_frames(true)`.
const STATE_CLASSES: u32 = class::CONTROLLER | class::BUS_OFF | class::RESTARTED;

/// A raw CAN socket bound to one interface.
pub struct SocketCanBus {
    socket: CanSocket,
    interface: String,
    filters: Vec<Filter>,
    error_frames: bool,
    state: ErrorState,
}

impl SocketCanBus {
    /// Opens a raw socket on `interface` (which must exist and be up to carry frames).
    pub fn open(interface: &str) -> io::Result<Self> {
        let socket = CanSocket::open(interface)?;
        socket.set_recv_timestamp(true)?;
        socket.set_error_filter(STATE_CLASSES)?;
        Ok(Self {
            socket,
            interface: interface.to_string(),
            filters: Vec::new(),
            error_frames: false,
            state: ErrorState::Active,
        })
    }

    /// The next frame or error frame from the socket, or `None` after `timeout`.
    fn read(&mut self, timeout: Option<Duration>) -> Result<Option<Message>, BusError> {
        // SO_RCVTIMEO: `None` blocks; a zero timeout would too, so wait at least 1 µs.
        let timeout = timeout.map(|t| t.max(Duration::from_micros(1)));
        self.socket.as_raw_socket().set_read_timeout(timeout)?;
        let (frame, time) = match self.socket.read_frame_with_timestamp() {
            Ok(read) => read,
            Err(e)
                if matches!(
                    e.kind(),
                    io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut
                ) =>
            {
                return Ok(None);
            }
            Err(e) => return Err(e.into()),
        };
        let at = time
            .duration_since(UNIX_EPOCH)
            .map_or(Timestamp::EPOCH, Timestamp::since_epoch);
        let raw: &libc::can_frame = frame.as_ref();
        Ok(Some(match decode(raw) {
            Ok(frame) => Message::rx(at, self.interface.clone(), frame).into_record(),
            Err(error) => Message::error(at, self.interface.clone(), error),
        }))
    }

    /// Follows the controller's state through the error frames that say it changed.
    fn track_state(&mut self, error: &ErrorFrame) {
        for e in &error.errors {
            self.state = match e {
                CanError::BusOff => ErrorState::BusOff,
                CanError::Restarted => ErrorState::Active,
                CanError::Controller(p)
                    if p.contains(ControllerProblems::RX_PASSIVE)
                        || p.contains(ControllerProblems::TX_PASSIVE) =>
                {
                    ErrorState::Passive
                }
                CanError::Controller(p) if p.contains(ControllerProblems::ACTIVE) => {
                    ErrorState::Active
                }
                _ => continue,
            };
        }
    }
}

/// A kernel frame as a buslab frame, or the error frame it is.
fn decode(raw: &libc::can_frame) -> Result<Frame, ErrorFrame> {
    let len = usize::from(raw.can_dlc.min(8));
    if raw.can_id & ERR_FLAG != 0 {
        return Err(ErrorFrame::decode(raw.can_id & ERR_MASK, &raw.data[..len]).unwrap_or_default());
    }
    let id = if raw.can_id & EFF_FLAG != 0 {
        Id::extended(raw.can_id & EFF_MASK)
    } else {
        Id::standard((raw.can_id & libc::CAN_SFF_MASK) as u16)
    }
    .expect("masked to the ID's width");
    let frame = if raw.can_id & RTR_FLAG != 0 {
        Frame::remote(id, raw.can_dlc.min(8))
    } else {
        Frame::data(id, &raw.data[..len])
    };
    Ok(frame.expect("at most 8 bytes"))
}

/// A buslab frame as the kernel's.
fn encode(frame: &Frame) -> libc::can_frame {
    let mut raw = can_frame_default();
    raw.can_id = frame.id().as_raw();
    if frame.is_extended() {
        raw.can_id |= EFF_FLAG;
    }
    if frame.is_remote() {
        raw.can_id |= RTR_FLAG;
    }
    raw.can_dlc = frame.dlc();
    raw.data[..frame.payload().len()].copy_from_slice(frame.payload());
    raw
}

/// python-can filters as kernel filters. A filter no 29-bit ID can match (such as
/// [`Filter::NONE`]) is left out; when only such filters are given, nothing passes.
fn kernel_filters(filters: &[Filter]) -> Option<Vec<CanFilter>> {
    let possible: Vec<CanFilter> = filters
        .iter()
        .filter(|f| f.id & f.mask & !EFF_MASK == 0)
        .map(|f| {
            let (id, mask) = (f.id & EFF_MASK, f.mask & EFF_MASK);
            match f.extended {
                Some(true) => CanFilter::new(id | EFF_FLAG, mask | EFF_FLAG),
                Some(false) => CanFilter::new(id, mask | EFF_FLAG),
                None => CanFilter::new(id, mask),
            }
        })
        .collect();
    (!possible.is_empty() || filters.is_empty()).then_some(possible)
}

impl CanBus for SocketCanBus {
    fn send(&mut self, frame: &Frame) -> Result<(), BusError> {
        let raw = CanFrame::from(encode(frame));
        match self.socket.write_frame(&raw) {
            Ok(()) => Ok(()),
            // The interface's transmit queue is full: CAN sockets say so instead of blocking.
            Err(e) if e.raw_os_error() == Some(libc::ENOBUFS) => Err(BusError::QueueFull(format!(
                "{}: the interface's transmit queue is full",
                self.interface
            ))),
            Err(e) => Err(e.into()),
        }
    }

    fn recv(&mut self, timeout: Option<Duration>) -> Result<Option<Message<Frame>>, BusError> {
        let deadline = timeout.map(|t| std::time::Instant::now() + t);
        loop {
            let left = deadline.map(|d| d.saturating_duration_since(std::time::Instant::now()));
            let Some(m) = self.read(left)? else {
                return Ok(None);
            };
            match &m.record {
                Record::Frame(frame) if matches_any(&self.filters, frame) => {
                    return Ok(m.into_frame());
                }
                Record::Error(error) => self.track_state(error),
                Record::Frame(_) | Record::Fd(_) => {}
            }
            if left.is_some_and(|l| l.is_zero()) {
                return Ok(None);
            }
        }
    }

    fn recv_event(&mut self, timeout: Option<Duration>) -> Result<Option<Message>, BusError> {
        if !self.error_frames {
            return Ok(self.recv(timeout)?.map(Message::into_record));
        }
        let deadline = timeout.map(|t| std::time::Instant::now() + t);
        loop {
            let left = deadline.map(|d| d.saturating_duration_since(std::time::Instant::now()));
            let Some(m) = self.read(left)? else {
                return Ok(None);
            };
            match &m.record {
                Record::Frame(frame) if !matches_any(&self.filters, frame) => {}
                Record::Error(error) => {
                    self.track_state(error);
                    return Ok(Some(m));
                }
                Record::Frame(_) | Record::Fd(_) => return Ok(Some(m)),
            }
            if left.is_some_and(|l| l.is_zero()) {
                return Ok(None);
            }
        }
    }

    fn set_error_frames(&mut self, on: bool) -> Result<(), BusError> {
        self.socket
            .set_error_filter(if on { ERR_MASK } else { STATE_CLASSES })?;
        self.error_frames = on;
        Ok(())
    }

    /// Filters in the kernel (fewer wake-ups), checked again here as python-can does.
    fn set_filters(&mut self, filters: &[Filter]) -> Result<(), BusError> {
        match kernel_filters(filters) {
            Some(k) if k.is_empty() => self.socket.set_filter_accept_all()?,
            Some(k) => self.socket.set_filters(&k)?,
            None => self.socket.set_filter_drop_all()?,
        }
        self.filters = filters.to_vec();
        Ok(())
    }

    /// The state the kernel last reported in an error frame (error-active until one says
    /// otherwise).
    fn state(&mut self) -> Result<ErrorState, BusError> {
        Ok(self.state)
    }

    fn channel_info(&self) -> String {
        format!("SocketCAN interface {}", self.interface)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(text: &str) -> Frame {
        text.parse().unwrap()
    }

    #[test]
    fn frames_cross_the_kernel_layout_both_ways() {
        for text in [
            "123#1122",
            "12345678#",
            "7FF#R3",
            "1FFFFFFF#R",
            "000#0102030405060708",
        ] {
            let raw = encode(&frame(text));
            assert_eq!(decode(&raw), Ok(frame(text)), "{text}");
        }
        let raw = encode(&frame("12345678#AA"));
        assert_eq!(raw.can_id, 0x9234_5678);
        assert_eq!(raw.can_dlc, 1);
    }

    #[test]
    fn error_frames_are_typed() {
        let mut raw = can_frame_default();
        raw.can_id = ERR_FLAG | class::PROTOCOL | class::BUS_ERROR;
        raw.can_dlc = 8;
        raw.data = [0, 0, 0x04, 0x02, 0, 0, 0, 0];
        let error = decode(&raw).unwrap_err();
        assert_eq!(error.class(), 0x088);
    }

    #[test]
    fn filters_become_kernel_filters_with_the_format_flag() {
        let k = kernel_filters(&[Filter::standard(0x123), Filter::extended(0x123)]).unwrap();
        let raw: Vec<(u32, u32)> = k
            .iter()
            .map(|f| {
                let f: &libc::can_filter = f.as_ref();
                (f.can_id, f.can_mask)
            })
            .collect();
        assert_eq!(
            raw,
            [
                (0x123, 0x7FF | EFF_FLAG),
                (0x123 | EFF_FLAG, 0x1FFF_FFFF | EFF_FLAG)
            ]
        );
        assert_eq!(kernel_filters(&[Filter::NONE]), None, "nothing passes");
        assert_eq!(kernel_filters(&[]), Some(vec![]), "everything passes");
    }
}
