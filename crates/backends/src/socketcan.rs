//! Linux SocketCAN (`socketcan:IFACE`): a raw CAN socket on an interface (`can0`, `vcan0`,
//! `slcan0`), with the kernel's receive timestamps, ID filters in the kernel, and error
//! frames decoded into [`ErrorFrame`]s.
//!
//! As with candump, the socket does not receive the frames it sends itself (the kernel's
//! `CAN_RAW_RECV_OWN_MSGS` is off), but it does receive those of other programs on the same
//! interface.
//!
//! CAN FD: an interface whose MTU is 72 (`ip link set vcan0 mtu 72`) carries FD frames; the
//! socket is then opened with `CAN_RAW_FD_FRAMES` and FD frames go both ways (read from
//! [`CanBus::recv_event`], sent with [`CanBus::send_fd`]). On an interface with MTU 16 the
//! socket is the classic one it always was, and an FD frame is refused naming the MTU. The MTU
//! is read once, when the bus is opened (as cansend reads it before each frame).
//!
//! Once [`CanBus::recv_waker`] was asked for, a wait for frames polls the socket beside a
//! [`WakeLine`], so a pump hands a frame to an idle bus at once (and waits with poll(2), whose
//! timeout is not rounded up to whole scheduler ticks as SO_RCVTIMEO's is).

use std::io;
use std::os::fd::{AsFd, AsRawFd};
use std::sync::Arc;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use buslab_bus::bus::matches_any;
use buslab_bus::error_frame::class;
use buslab_bus::{
    BusError, CanBus, CanError, ControllerProblems, ErrorFrame, ErrorState, FdSupport, Filter,
    Message, NoFd, Record, RecvWaker, Timestamp, matches_any_id,
};
use buslab_can::{FD_LENGTHS, FdFrame, Frame, Id};
use buslab_link::wake::{WakeLine, wait_readable};
use socketcan::frame::{can_frame_default, canfd_frame_default};
use socketcan::{
    CanAnyFrame, CanFdFrame, CanFdSocket, CanFilter, CanFrame, CanSocket, Socket, SocketOptions,
};

const EFF_FLAG: u32 = libc::CAN_EFF_FLAG;
const RTR_FLAG: u32 = libc::CAN_RTR_FLAG;
const ERR_FLAG: u32 = libc::CAN_ERR_FLAG;
const EFF_MASK: u32 = libc::CAN_EFF_MASK;
const ERR_MASK: u32 = libc::CAN_ERR_MASK;
const BRS: u8 = libc::CANFD_BRS as u8;
const ESI: u8 = libc::CANFD_ESI as u8;
const FDF: u8 = libc::CANFD_FDF as u8;

/// Error classes the bus always asks the kernel for, to know its state; they reach the user
/// only after `set_error_frames(true)`.
const STATE_CLASSES: u32 = class::CONTROLLER | class::BUS_OFF | class::RESTARTED;

/// The socket: classic (`can_frame` only) or with `CAN_RAW_FD_FRAMES` on an FD interface.
enum Raw {
    Classic(CanSocket),
    Fd(CanFdSocket),
}

/// The same call on either kind of socket.
macro_rules! on_socket {
    ($raw:expr, $s:ident => $call:expr) => {
        match $raw {
            Raw::Classic($s) => $call,
            Raw::Fd($s) => $call,
        }
    };
}

/// What one read gave: a classic frame (or error frame) or an FD frame, in the kernel's layout.
enum Read {
    Classic(libc::can_frame),
    Fd(libc::canfd_frame),
}

/// A raw CAN socket bound to one interface.
pub struct SocketCanBus {
    socket: Raw,
    interface: String,
    /// The interface's MTU when the bus was opened (16 classic, 72 FD).
    mtu: u32,
    filters: Vec<Filter>,
    error_frames: bool,
    state: ErrorState,
    /// Ends a wait for frames from another thread, once [`CanBus::recv_waker`] asked for it.
    wake: Option<WakeLine>,
}

impl SocketCanBus {
    /// Opens a raw socket on `interface` (which must exist and be up to carry frames); with
    /// FD frames when the interface's MTU is 72.
    pub fn open(interface: &str) -> io::Result<Self> {
        let classic = CanSocket::open(interface)?;
        let mtu = interface_mtu(&classic, interface)?;
        let socket = if mtu as usize == libc::CANFD_MTU {
            Raw::Fd(CanFdSocket::try_from(classic)?)
        } else {
            Raw::Classic(classic)
        };
        on_socket!(&socket, s => {
            s.set_recv_timestamp(true)?;
            s.set_error_filter(STATE_CLASSES)?;
        });
        Ok(Self {
            socket,
            interface: interface.to_string(),
            mtu,
            filters: Vec::new(),
            error_frames: false,
            state: ErrorState::Active,
            wake: None,
        })
    }

    /// The next frame, FD frame or error frame from the socket, or `None` after `timeout` (or
    /// when woken).
    fn read(&mut self, timeout: Option<Duration>) -> Result<Option<Message>, BusError> {
        let timeout = match &self.wake {
            Some(wake) if !wait_for_frame(&self.socket, wake, timeout)? => return Ok(None),
            // The poll waited: the read below must not wait again.
            Some(_) => Some(Duration::ZERO),
            None => timeout,
        };
        // SO_RCVTIMEO: `None` blocks; a zero timeout would too, so wait at least 1 µs.
        let timeout = timeout.map(|t| t.max(Duration::from_micros(1)));
        on_socket!(&self.socket, s => s.as_raw_socket().set_read_timeout(timeout))?;
        let read = match &self.socket {
            Raw::Classic(s) => s
                .read_frame_with_timestamp()
                .map(|(frame, time)| (Read::Classic(*frame.as_ref()), time)),
            Raw::Fd(s) => s.read_frame_with_timestamp().map(|(frame, time)| {
                let raw = match frame {
                    CanAnyFrame::Normal(f) => Read::Classic(*f.as_ref()),
                    CanAnyFrame::Remote(f) => Read::Classic(*f.as_ref()),
                    CanAnyFrame::Error(f) => Read::Classic(*f.as_ref()),
                    CanAnyFrame::Fd(f) => Read::Fd(*f.as_ref()),
                };
                (raw, time)
            }),
        };
        let (raw, time) = match read {
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
        let at = stamp(time);
        let channel = self.interface.clone();
        Ok(Some(match raw {
            Read::Classic(raw) => match decode(&raw) {
                Ok(frame) => Message::rx(at, channel, frame).into_record(),
                Err(error) => Message::error(at, channel, error),
            },
            Read::Fd(raw) => Message::fd(at, channel, decode_fd(&raw)),
        }))
    }

    /// Whether a received record passes the filters (error frames are not filtered by ID).
    fn passes(&self, record: &Record) -> bool {
        match record {
            Record::Frame(frame) => matches_any(&self.filters, frame),
            Record::Fd(frame) => matches_any_id(&self.filters, frame.id()),
            Record::Error(_) => true,
        }
    }

    /// A write's outcome as the bus tells it.
    fn sent(&self, written: io::Result<()>) -> Result<(), BusError> {
        match written {
            Ok(()) => Ok(()),
            // The interface's transmit queue is full: CAN sockets say so instead of blocking.
            Err(e) if e.raw_os_error() == Some(libc::ENOBUFS) => Err(BusError::QueueFull(format!(
                "{}: the interface's transmit queue is full",
                self.interface
            ))),
            Err(e) => Err(e.into()),
        }
    }

    fn refused_fd(&self) -> BusError {
        BusError::ClassicOnly {
            bus: self.channel_info(),
            why: NoFd::ClassicInterface {
                interface: self.interface.clone(),
                mtu: self.mtu,
            },
        }
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

/// Waits until `socket` has a frame (`true`), or `timeout` passed or `wake` was woken. A
/// signal does not end the wait: it goes on until the deadline.
fn wait_for_frame(socket: &Raw, wake: &WakeLine, timeout: Option<Duration>) -> io::Result<bool> {
    let deadline = timeout.map(|t| Instant::now() + t);
    loop {
        let left = deadline.map(|d| d.saturating_duration_since(Instant::now()));
        let fd = on_socket!(socket, s => s.as_raw_socket().as_fd());
        match wait_readable(fd, Some(wake), left) {
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            waited => return waited,
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

/// A kernel FD frame as buslab's. The kernel gives only FD lengths; any other is rounded up
/// to the next (its padding is zeros), as the socketcan crate does.
fn decode_fd(raw: &libc::canfd_frame) -> FdFrame {
    let id = if raw.can_id & EFF_FLAG != 0 {
        Id::extended(raw.can_id & EFF_MASK)
    } else {
        Id::standard((raw.can_id & libc::CAN_SFF_MASK) as u16)
    }
    .expect("masked to the ID's width");
    let len = FD_LENGTHS
        .into_iter()
        .find(|&l| l >= usize::from(raw.len))
        .unwrap_or(buslab_can::FD_MAX_LEN);
    FdFrame::new(id, &raw.data[..len])
        .expect("an FD length")
        .with_brs(raw.flags & BRS != 0)
        .with_esi(raw.flags & ESI != 0)
}

/// A buslab FD frame as the kernel's (with FDF, as kernels since 6.0 mark FD frames).
fn encode_fd(frame: &FdFrame) -> libc::canfd_frame {
    let mut raw = canfd_frame_default();
    raw.can_id = frame.id().as_raw();
    if frame.is_extended() {
        raw.can_id |= EFF_FLAG;
    }
    raw.flags = FDF | if frame.brs() { BRS } else { 0 } | if frame.esi() { ESI } else { 0 };
    raw.len = frame.payload().len() as u8;
    raw.data[..frame.payload().len()].copy_from_slice(frame.payload());
    raw
}

/// The interface's MTU (16: classic CAN, 72: CAN FD), asked as cansend asks it.
fn interface_mtu(socket: &CanSocket, interface: &str) -> io::Result<u32> {
    // SAFETY: `ifreq` is plain data (zeroes are a valid value); the kernel reads the name,
    // which is NUL-terminated within IFNAMSIZ (longer names were refused when the socket was
    // bound), and writes the MTU into the union.
    #[allow(unsafe_code)]
    let mtu = unsafe {
        let mut req: libc::ifreq = std::mem::zeroed();
        for (dst, &src) in req
            .ifr_name
            .iter_mut()
            .zip(interface.as_bytes().iter().take(libc::IFNAMSIZ - 1))
        {
            *dst = src as libc::c_char;
        }
        if libc::ioctl(socket.as_raw_fd(), libc::SIOCGIFMTU as _, &mut req) < 0 {
            return Err(io::Error::last_os_error());
        }
        req.ifr_ifru.ifru_mtu
    };
    Ok(mtu.max(0) as u32)
}

fn stamp(time: SystemTime) -> Timestamp {
    time.duration_since(UNIX_EPOCH)
        .map_or(Timestamp::EPOCH, Timestamp::since_epoch)
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
    fn fd_support(&self) -> FdSupport {
        match self.socket {
            Raw::Fd(_) => FdSupport::Carried,
            Raw::Classic(_) => FdSupport::Classic(NoFd::ClassicInterface {
                interface: self.interface.clone(),
                mtu: self.mtu,
            }),
        }
    }

    fn send(&mut self, frame: &Frame) -> Result<(), BusError> {
        let raw = CanFrame::from(encode(frame));
        let sent = on_socket!(&self.socket, s => s.write_frame(&raw));
        self.sent(sent)
    }

    fn send_fd(&mut self, frame: &FdFrame) -> Result<(), BusError> {
        let Raw::Fd(socket) = &self.socket else {
            return Err(self.refused_fd());
        };
        match socket.write_frame(&CanFdFrame::from(encode_fd(frame))) {
            // The interface's MTU went down to 16 since the bus was opened.
            Err(e) if e.raw_os_error() == Some(libc::EINVAL) => Err(self.refused_fd()),
            sent => self.sent(sent),
        }
    }

    fn recv(&mut self, timeout: Option<Duration>) -> Result<Option<Message<Frame>>, BusError> {
        let deadline = timeout.map(|t| Instant::now() + t);
        loop {
            let left = deadline.map(|d| d.saturating_duration_since(Instant::now()));
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

    /// Frames, FD frames (on an FD interface) and, once asked for, error frames.
    fn recv_event(&mut self, timeout: Option<Duration>) -> Result<Option<Message>, BusError> {
        let deadline = timeout.map(|t| Instant::now() + t);
        loop {
            let left = deadline.map(|d| d.saturating_duration_since(Instant::now()));
            let Some(m) = self.read(left)? else {
                return Ok(None);
            };
            if let Record::Error(error) = &m.record {
                self.track_state(error);
                if self.error_frames {
                    return Ok(Some(m));
                }
            } else if self.passes(&m.record) {
                return Ok(Some(m));
            }
            if left.is_some_and(|l| l.is_zero()) {
                return Ok(None);
            }
        }
    }

    fn set_error_frames(&mut self, on: bool) -> Result<(), BusError> {
        on_socket!(&self.socket, s => s.set_error_filter(if on { ERR_MASK } else { STATE_CLASSES }))?;
        self.error_frames = on;
        Ok(())
    }

    /// Filters in the kernel (fewer wake-ups), checked again here as python-can does.
    fn set_filters(&mut self, filters: &[Filter]) -> Result<(), BusError> {
        on_socket!(&self.socket, s => match kernel_filters(filters) {
            Some(k) if k.is_empty() => s.set_filter_accept_all()?,
            Some(k) => s.set_filters(&k)?,
            None => s.set_filter_drop_all()?,
        });
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

    fn recv_waker(&mut self) -> Option<Arc<dyn RecvWaker>> {
        let bus = self.channel_info();
        WakeLine::opened_waker(&mut self.wake, &bus)
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
    fn fd_frames_cross_the_kernel_layout_both_ways() {
        let full = format!("7FF##1{}", "A5".repeat(64));
        for text in [
            "123##0",
            "123##1112233",
            "1FFFFFFF##3112233445566778899AABBCC",
            "000##2",
            &full,
        ] {
            let fd: FdFrame = text.parse().unwrap();
            let raw = encode_fd(&fd);
            assert_eq!(decode_fd(&raw), fd, "{text}");
        }
        let raw = encode_fd(&"12345678##3AABB".parse().unwrap());
        assert_eq!(raw.can_id, 0x9234_5678);
        assert_eq!((raw.len, raw.flags), (2, FDF | BRS | ESI));
    }

    #[test]
    fn a_kernel_fd_length_between_fd_lengths_is_rounded_up_with_zeros() {
        let mut raw = canfd_frame_default();
        raw.can_id = 0x123;
        raw.len = 10;
        raw.data[..10].copy_from_slice(&[1; 10]);
        let fd = decode_fd(&raw);
        assert_eq!(fd.payload().len(), 12);
        assert_eq!(&fd.payload()[10..], [0, 0]);
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
