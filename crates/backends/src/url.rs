//! Bus URLs: which backend, and where (`socketcand://HOST[:PORT]/CHANNEL`, `socketcan:IFACE`,
//! `slcan:DEVICE[@BAUD][?bitrate=N&data_bitrate=N&fd=1&listen_only=1]`).

use std::fmt;

/// socketcand's port.
pub const SOCKETCAND_PORT: u16 = 29536;
/// The channel a socketcand URL without one opens.
pub const DEFAULT_CHANNEL: &str = "vcan0";

/// Where a bus is: a parsed bus URL.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub enum BusUrl {
    /// socketcand raw mode over TCP.
    Socketcand {
        host: String,
        port: u16,
        channel: String,
    },
    /// A Linux SocketCAN interface.
    SocketCan { interface: String },
    /// An SLCAN (Lawicel) serial adapter: the device, its line's baud rate, the CAN bit rate,
    /// whether to open it listen-only, whether it speaks CAN FD and the FD data bit rate to
    /// set (which implies FD).
    Slcan {
        device: String,
        baud: Option<u32>,
        bitrate: Option<u32>,
        listen_only: bool,
        fd: bool,
        data_bitrate: Option<u32>,
    },
    /// cannelloni: SocketCAN frames over UDP (point to point: frames go to the peer's
    /// `host:port`, come in on `listen`) or over TCP (this side connects to `host:port`, or
    /// with `role=server` listens there for one peer at a time).
    Cannelloni {
        transport: CannelloniTransport,
        host: String,
        port: u16,
        /// UDP: where this side listens (`0.0.0.0:PORT`, the peer's port, if not given).
        listen: Option<(String, u16)>,
    },
    /// An MQTT broker: frames in envelopes on `PREFIX/frames`, each member's status on
    /// `PREFIX/status/ORIGIN` (retained, last will `offline`) and counters on
    /// `PREFIX/stats/ORIGIN` (retained).
    Mqtt {
        host: String,
        port: u16,
        prefix: String,
        /// `mqtts://`: TLS to the broker.
        tls: bool,
    },
}

/// How cannelloni travels.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum CannelloniTransport {
    Udp,
    /// Connects to the peer (what PyPI's can-cannelloni does).
    TcpClient,
    /// Listens for one peer at a time (cannelloni's `-C s`).
    TcpServer,
}

/// cannelloni's usual port.
pub const CANNELLONI_PORT: u16 = 20000;
/// MQTT's port without TLS, and with it.
pub const MQTT_PORT: u16 = 1883;
pub const MQTTS_PORT: u16 = 8883;

/// A bus URL that cannot be read, with what is wrong.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("bus URL {url:?}: {problem}")]
pub struct UrlError {
    pub url: String,
    pub problem: UrlProblem,
}

/// What is wrong with a bus URL.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum UrlProblem {
    #[error("unknown backend {scheme:?}: expected {expected}")]
    UnknownScheme { scheme: String, expected: String },
    #[error("expected {expected}")]
    Syntax { expected: &'static str },
    #[error("has no host")]
    NoHost,
    #[error(
        "host {0:?} must be a host name or an IP address (letters, digits, '.', '-', '_'; IPv6 in brackets, '%' before a zone)"
    )]
    Host(String),
    #[error("unclosed [ in the host")]
    UnclosedBracket,
    #[error("expected :PORT or nothing after ], got {0:?}")]
    AfterBracket(String),
    #[error("port {0:?} must be a number 1..65535")]
    Port(String),
    #[error(
        "channel {0:?} must be one name: 1..64 printable ASCII characters without spaces, /, < or >"
    )]
    Channel(String),
    #[error("interface {0:?} must be 1..15 characters without spaces or /")]
    Interface(String),
    #[error("has no device")]
    NoDevice,
    #[error("baud rate {0:?} must be a number of bit/s 1..4000000")]
    Baud(String),
    #[error("bitrate {0:?} must be a number of bit/s 1..1000000")]
    Bitrate(String),
    #[error("unknown option {0:?}: slcan takes ?bitrate=N&data_bitrate=N&fd=1&listen_only=1")]
    Option(String),
    #[error("{0}={1:?} must be 0 or 1")]
    Switch(&'static str, String),
    #[error(
        "data_bitrate {0:?} must be one of SLCAN's Y rates: 500000, 1000000, 2000000, 3000000, 4000000, 5000000, 8000000"
    )]
    DataBitrate(String),
    #[error(
        "unknown option {0:?}: cannelloni takes ?listen=HOST:PORT (UDP) or ?role=client|server (TCP)"
    )]
    CannelloniOption(String),
    #[error(
        "a user name or password in the URL is refused (it would show in process lists and shell history): set $BUSLAB_MQTT_USERNAME and $BUSLAB_MQTT_PASSWORD"
    )]
    Credentials,
    #[error(
        "topic prefix {0:?} must be 1..200 characters of one or more levels, without +, #, spaces, empty levels or a leading /"
    )]
    Prefix(String),
    #[error(
        "unknown option {0:?}: mqtt takes no options (a user name and password are never part of the URL: they come from $BUSLAB_MQTT_USERNAME and $BUSLAB_MQTT_PASSWORD)"
    )]
    MqttOption(String),
    #[error(
        "bus name {0:?}: expected an interface name (vcan0, can0), a device path or a bus URL ({1})"
    )]
    Name(String, String),
}

impl UrlError {
    pub(crate) fn new(url: &str, problem: UrlProblem) -> Self {
        Self {
            url: url.to_string(),
            problem,
        }
    }
}

/// The interface name that means buslab's own bus: `buslab bus serve`'s or `buslab lab`'s on
/// this machine, [`crate::DEFAULT_URL`].
pub const DEFAULT_NAME: &str = "vcan0";

/// `socketcand://HOST[:PORT][/CHANNEL]` (port 29536 and channel vcan0 by default; IPv6 as
/// `[::1]`).
pub(crate) fn parse_socketcand(url: &str) -> Result<BusUrl, UrlError> {
    let err = |p| UrlError::new(url, p);
    let rest = url.strip_prefix("socketcand://").ok_or_else(|| {
        err(UrlProblem::Syntax {
            expected: "socketcand://HOST[:PORT][/CHANNEL]",
        })
    })?;
    let (hostport, channel) = rest.split_once('/').unwrap_or((rest, DEFAULT_CHANNEL));
    let channel = if channel.is_empty() {
        DEFAULT_CHANNEL
    } else {
        channel
    };
    if channel.len() > 64
        || !channel
            .bytes()
            .all(|b| b.is_ascii_graphic() && !matches!(b, b'/' | b'<' | b'>'))
    {
        return Err(err(UrlProblem::Channel(channel.to_string())));
    }
    let (host, port) = host_port(url, hostport, SOCKETCAND_PORT)?;
    Ok(BusUrl::Socketcand {
        host,
        port,
        channel: channel.to_string(),
    })
}

/// `HOST[:PORT]` as socketcand URLs write it (IPv6 in brackets, `default` without a port).
pub(crate) fn host_port(
    url: &str,
    hostport: &str,
    default: u16,
) -> Result<(String, u16), UrlError> {
    let err = |p| UrlError::new(url, p);
    let parse_port = |p: &str| {
        p.parse::<u16>()
            .ok()
            .filter(|&n| n != 0 && p.bytes().all(|b| b.is_ascii_digit()))
            .ok_or_else(|| err(UrlProblem::Port(p.to_string())))
    };
    let (host, port) = if let Some(bracketed) = hostport.strip_prefix('[') {
        // An IPv6 address: `[::1]` or `[::1]:PORT`.
        let (h, after) = bracketed
            .split_once(']')
            .ok_or_else(|| err(UrlProblem::UnclosedBracket))?;
        let port = match after {
            "" => default,
            _ => parse_port(
                after
                    .strip_prefix(':')
                    .ok_or_else(|| err(UrlProblem::AfterBracket(after.to_string())))?,
            )?,
        };
        (h, port)
    } else {
        match hostport.rsplit_once(':') {
            None => (hostport, default),
            // `fe80::1` without brackets: an IPv6 address on the default port (a port after
            // an IPv6 address needs the brackets).
            Some((h, _)) if h.contains(':') => (hostport, default),
            Some((h, p)) => (h, parse_port(p)?),
        }
    };
    if host.is_empty() {
        return Err(err(UrlProblem::NoHost));
    }
    // Anything else (brackets, spaces, control characters) would not print back as this URL.
    if !host
        .bytes()
        .all(|b| b.is_ascii_alphanumeric() || matches!(b, b'.' | b'-' | b'_' | b':' | b'%'))
    {
        return Err(err(UrlProblem::Host(host.to_string())));
    }
    Ok((host.to_string(), port))
}

/// `cannelloni://HOST:PORT[?listen=HOST:PORT]` (UDP) and
/// `cannelloni+tcp://HOST:PORT[?role=client|server]`.
pub(crate) fn parse_cannelloni(url: &str) -> Result<BusUrl, UrlError> {
    let err = |p| UrlError::new(url, p);
    let (transport, rest) = if let Some(rest) = url.strip_prefix("cannelloni://") {
        (CannelloniTransport::Udp, rest)
    } else if let Some(rest) = url.strip_prefix("cannelloni+tcp://") {
        (CannelloniTransport::TcpClient, rest)
    } else {
        return Err(err(UrlProblem::Syntax {
            expected: "cannelloni://HOST:PORT[?listen=HOST:PORT] or cannelloni+tcp://HOST:PORT[?role=server]",
        }));
    };
    let (hostport, query) = rest.split_once('?').unwrap_or((rest, ""));
    let (host, port) = host_port(url, hostport.trim_end_matches('/'), CANNELLONI_PORT)?;
    let mut transport = transport;
    let mut listen = None;
    for option in query.split('&').filter(|o| !o.is_empty()) {
        match (transport, option.split_once('=')) {
            (CannelloniTransport::Udp, Some(("listen", v))) if listen.is_none() => {
                listen = Some(host_port(url, v, port)?);
            }
            (CannelloniTransport::TcpClient, Some(("role", "server"))) => {
                transport = CannelloniTransport::TcpServer;
            }
            (CannelloniTransport::TcpClient, Some(("role", "client"))) => {}
            _ => return Err(err(UrlProblem::CannelloniOption(option.to_string()))),
        }
    }
    Ok(BusUrl::Cannelloni {
        transport,
        host,
        port,
        listen,
    })
}

/// `mqtt://BROKER[:PORT]/PREFIX` and `mqtts://…` (TLS).
pub(crate) fn parse_mqtt(url: &str) -> Result<BusUrl, UrlError> {
    let err = |p| UrlError::new(url, p);
    let (tls, rest) = if let Some(rest) = url.strip_prefix("mqtt://") {
        (false, rest)
    } else if let Some(rest) = url.strip_prefix("mqtts://") {
        (true, rest)
    } else {
        return Err(err(UrlProblem::Syntax {
            expected: "mqtt://BROKER[:PORT]/TOPIC-PREFIX",
        }));
    };
    let (rest, query) = rest.split_once('?').unwrap_or((rest, ""));
    if !query.is_empty() {
        return Err(err(UrlProblem::MqttOption(query.to_string())));
    }
    let (hostport, prefix) = rest.split_once('/').unwrap_or((rest, ""));
    if hostport.contains('@') {
        return Err(err(UrlProblem::Credentials));
    }
    let (host, port) = host_port(url, hostport, if tls { MQTTS_PORT } else { MQTT_PORT })?;
    let prefix = prefix.strip_suffix('/').unwrap_or(prefix);
    if prefix.is_empty()
        || prefix.len() > 200
        || prefix.split('/').any(str::is_empty)
        || !prefix
            .bytes()
            .all(|b| b.is_ascii_graphic() && !matches!(b, b'+' | b'#'))
    {
        return Err(err(UrlProblem::Prefix(prefix.to_string())));
    }
    Ok(BusUrl::Mqtt {
        host,
        port,
        prefix: prefix.to_string(),
        tls,
    })
}

/// `socketcan:IFACE` (a Linux interface name: 1..15 characters).
pub(crate) fn parse_socketcan(url: &str) -> Result<BusUrl, UrlError> {
    let interface = url.strip_prefix("socketcan:").ok_or_else(|| {
        UrlError::new(
            url,
            UrlProblem::Syntax {
                expected: "socketcan:IFACE",
            },
        )
    })?;
    if !(1..=15).contains(&interface.len())
        || !interface.bytes().all(|b| b.is_ascii_graphic() && b != b'/')
    {
        return Err(UrlError::new(
            url,
            UrlProblem::Interface(interface.to_string()),
        ));
    }
    Ok(BusUrl::SocketCan {
        interface: interface.to_string(),
    })
}

/// `slcan:DEVICE[@BAUD][?bitrate=N&data_bitrate=N&fd=1&listen_only=1]`.
pub(crate) fn parse_slcan(url: &str) -> Result<BusUrl, UrlError> {
    let err = |p| UrlError::new(url, p);
    let rest = url.strip_prefix("slcan:").ok_or_else(|| {
        err(UrlProblem::Syntax {
            expected: "slcan:DEVICE[@BAUD][?bitrate=N]",
        })
    })?;
    let (path, query) = rest.split_once('?').unwrap_or((rest, ""));
    let number = |text: &str, max: u32| {
        text.parse::<u32>()
            .ok()
            .filter(|n| (1..=max).contains(n) && text.bytes().all(|b| b.is_ascii_digit()))
    };
    let (device, baud) = match path.rsplit_once('@') {
        Some((d, b)) => (
            d,
            Some(number(b, 4_000_000).ok_or_else(|| err(UrlProblem::Baud(b.to_string())))?),
        ),
        None => (path, None),
    };
    if device.is_empty() {
        return Err(err(UrlProblem::NoDevice));
    }
    let switch = |name: &'static str, v: &str| match v {
        "0" => Ok(false),
        "1" => Ok(true),
        _ => Err(err(UrlProblem::Switch(name, v.to_string()))),
    };
    let mut bitrate = None;
    let mut listen_only = None;
    let mut fd = None;
    let mut data_bitrate = None;
    for option in query.split('&').filter(|o| !o.is_empty()) {
        match option.split_once('=') {
            Some(("bitrate", v)) if bitrate.is_none() => {
                bitrate = Some(
                    number(v, 1_000_000).ok_or_else(|| err(UrlProblem::Bitrate(v.to_string())))?,
                );
            }
            Some(("listen_only", v)) if listen_only.is_none() => {
                listen_only = Some(switch("listen_only", v)?);
            }
            Some(("fd", v)) if fd.is_none() => fd = Some(switch("fd", v)?),
            Some(("data_bitrate", v)) if data_bitrate.is_none() => {
                data_bitrate = Some(
                    number(v, u32::MAX)
                        .filter(|r| buslab_slcan::DATA_BITRATES.iter().any(|(_, d)| d == r))
                        .ok_or_else(|| err(UrlProblem::DataBitrate(v.to_string())))?,
                );
            }
            _ => return Err(err(UrlProblem::Option(option.to_string()))),
        }
    }
    Ok(BusUrl::Slcan {
        device: device.to_string(),
        baud,
        bitrate,
        listen_only: listen_only.unwrap_or(false),
        // A data bit rate is CAN FD's.
        fd: fd.unwrap_or(false) || data_bitrate.is_some(),
        data_bitrate,
    })
}

impl BusUrl {
    /// The URL's scheme, the registry's key: `socketcand`, `socketcan`, `slcan`.
    pub fn scheme(&self) -> &'static str {
        match self {
            BusUrl::Socketcand { .. } => "socketcand",
            BusUrl::SocketCan { .. } => "socketcan",
            BusUrl::Slcan { .. } => "slcan",
            BusUrl::Cannelloni {
                transport: CannelloniTransport::Udp,
                ..
            } => "cannelloni",
            BusUrl::Cannelloni { .. } => "cannelloni+tcp",
            BusUrl::Mqtt { tls: false, .. } => "mqtt",
            BusUrl::Mqtt { tls: true, .. } => "mqtts",
        }
    }

    /// The channel name shown in candump-like output.
    pub fn channel(&self) -> &str {
        match self {
            BusUrl::Socketcand { channel, .. } => channel,
            BusUrl::SocketCan { interface } => interface,
            BusUrl::Slcan { device, .. } => device.rsplit('/').next().unwrap_or(device),
            BusUrl::Cannelloni { .. } => "cannelloni",
            BusUrl::Mqtt { prefix, .. } => prefix,
        }
    }
}

/// `host:port`, an IPv6 host in brackets.
fn bracketed(host: &str, port: u16) -> String {
    if host.contains(':') {
        format!("[{host}]:{port}")
    } else {
        format!("{host}:{port}")
    }
}

/// The URL in its full form (defaults written out).
impl fmt::Display for BusUrl {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            BusUrl::Socketcand {
                host,
                port,
                channel,
            } if host.contains(':') => write!(f, "socketcand://[{host}]:{port}/{channel}"),
            BusUrl::Socketcand {
                host,
                port,
                channel,
            } => write!(f, "socketcand://{host}:{port}/{channel}"),
            BusUrl::SocketCan { interface } => write!(f, "socketcan:{interface}"),
            BusUrl::Slcan {
                device,
                baud,
                bitrate,
                listen_only,
                fd,
                data_bitrate,
            } => {
                write!(f, "slcan:{device}")?;
                if let Some(b) = baud {
                    write!(f, "@{b}")?;
                }
                let mut options = Vec::new();
                if let Some(r) = bitrate {
                    options.push(format!("bitrate={r}"));
                }
                match data_bitrate {
                    Some(r) => options.push(format!("data_bitrate={r}")),
                    None if *fd => options.push("fd=1".into()),
                    None => {}
                }
                if *listen_only {
                    options.push("listen_only=1".into());
                }
                if !options.is_empty() {
                    write!(f, "?{}", options.join("&"))?;
                }
                Ok(())
            }
            BusUrl::Cannelloni {
                transport,
                host,
                port,
                listen,
            } => {
                write!(f, "{}://{}", self.scheme(), bracketed(host, *port))?;
                match (transport, listen) {
                    (CannelloniTransport::Udp, Some((h, p))) => {
                        write!(f, "?listen={}", bracketed(h, *p))
                    }
                    (CannelloniTransport::TcpServer, _) => write!(f, "?role=server"),
                    _ => Ok(()),
                }
            }
            BusUrl::Mqtt {
                host, port, prefix, ..
            } => write!(f, "{}://{}/{prefix}", self.scheme(), bracketed(host, *port)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::resolve;

    fn url(text: &str) -> BusUrl {
        text.parse().unwrap_or_else(|e| panic!("{text}: {e}"))
    }

    #[test]
    fn socketcand_urls() {
        assert_eq!(
            url("socketcand://127.0.0.1:29537/can1"),
            BusUrl::Socketcand {
                host: "127.0.0.1".into(),
                port: 29537,
                channel: "can1".into()
            }
        );
        for (text, full) in [
            (
                "socketcand://127.0.0.1:29537/can1",
                "socketcand://127.0.0.1:29537/can1",
            ),
            (
                "socketcand://localhost",
                "socketcand://localhost:29536/vcan0",
            ),
            ("socketcand://h:1/", "socketcand://h:1/vcan0"),
            ("socketcand://[::1]:5/x", "socketcand://[::1]:5/x"),
            // A bracketed IPv6 host without a port takes the default one.
            ("socketcand://[::1]/x", "socketcand://[::1]:29536/x"),
            (
                "socketcand://[fe80::1]",
                "socketcand://[fe80::1]:29536/vcan0",
            ),
            // Without brackets an IPv6 address has no port.
            ("socketcand://fe80::1/x", "socketcand://[fe80::1]:29536/x"),
        ] {
            assert_eq!(url(text).to_string(), full, "{text}");
            assert_eq!(url(full), url(text), "{full}");
        }
        assert_eq!(url("socketcand://h/can1").channel(), "can1");
    }

    /// Found by fuzzing (`backends_spec`): a host with a bracket inside and a control
    /// character was taken as an IPv6 address on the default port, and printed as a URL that
    /// does not parse.
    #[test]
    fn socketcand_host_is_a_name_or_an_address() {
        for text in [
            "socketcand://\u{5}[::1]:295jjj36/can1",
            "socketcand://a[b/x",
            "socketcand://bad host:5/x",
            "socketcand://[a]b]:5/x",
        ] {
            let e = text.parse::<BusUrl>().unwrap_err();
            assert!(
                matches!(e.problem, UrlProblem::Host(_) | UrlProblem::AfterBracket(_)),
                "{text}: {e}"
            );
        }
        assert_eq!(
            url("socketcand://[fe80::1%eth0]:5/x").to_string(),
            "socketcand://[fe80::1%eth0]:5/x"
        );
        assert_eq!(
            url("socketcand://bench-2.lab_x:5/x").to_string(),
            "socketcand://bench-2.lab_x:5/x"
        );
    }

    #[test]
    fn other_backends_parse_for_their_slots() {
        assert_eq!(
            url("socketcan:can0"),
            BusUrl::SocketCan {
                interface: "can0".into()
            }
        );
        assert_eq!(
            url("slcan:/dev/ttyACM0@115200?bitrate=500000"),
            BusUrl::Slcan {
                device: "/dev/ttyACM0".into(),
                baud: Some(115_200),
                bitrate: Some(500_000),
                listen_only: false,
                fd: false,
                data_bitrate: None,
            }
        );
        let plain = url("slcan:/dev/ttyUSB0");
        assert_eq!(plain.to_string(), "slcan:/dev/ttyUSB0");
        assert_eq!(plain.channel(), "ttyUSB0");
        assert_eq!(plain.scheme(), "slcan");
    }

    #[test]
    fn names_resolve_as_can_utils_users_type_them() {
        for (name, want) in [
            ("vcan0", "socketcand://127.0.0.1:29536/vcan0"),
            ("can0", "socketcan:can0"),
            ("vcan1", "socketcan:vcan1"),
            ("slcan0", "socketcan:slcan0"),
            ("/dev/ttyACM0", "slcan:/dev/ttyACM0"),
            ("./adapter", "slcan:./adapter"),
            ("socketcan:vcan0", "socketcan:vcan0"),
            (
                "slcan:/dev/ttyUSB0@115200?bitrate=250000",
                "slcan:/dev/ttyUSB0@115200?bitrate=250000",
            ),
            ("socketcand://h/x", "socketcand://h:29536/x"),
        ] {
            assert_eq!(resolve(name).unwrap().to_string(), want, "{name}");
        }
        for (bad, want) in [
            ("", "bus name \"\": expected an interface name"),
            (
                "a very long interface",
                "expected an interface name (vcan0, can0)",
            ),
            ("tcp://x", "unknown backend \"tcp\""),
        ] {
            let err = resolve(bad).unwrap_err().to_string();
            assert!(err.contains(want), "{bad:?}: {err}");
        }
    }

    #[test]
    fn slcan_fd_is_an_option_and_a_data_bit_rate_implies_it() {
        let u = url("slcan:/dev/x?fd=1");
        assert!(matches!(
            u,
            BusUrl::Slcan {
                fd: true,
                data_bitrate: None,
                ..
            }
        ));
        assert_eq!(u.to_string(), "slcan:/dev/x?fd=1");
        let u = url("slcan:/dev/x?data_bitrate=2000000&bitrate=500000");
        assert!(matches!(
            u,
            BusUrl::Slcan {
                fd: true,
                data_bitrate: Some(2_000_000),
                ..
            }
        ));
        assert_eq!(
            u.to_string(),
            "slcan:/dev/x?bitrate=500000&data_bitrate=2000000"
        );
        assert_eq!(url(&u.to_string()), u);
        assert!(matches!(
            url("slcan:/dev/x?fd=0"),
            BusUrl::Slcan { fd: false, .. }
        ));
        for (bad, want) in [
            ("slcan:/dev/x?fd=yes", "fd=\"yes\" must be 0 or 1"),
            (
                "slcan:/dev/x?data_bitrate=6000000",
                "data_bitrate \"6000000\" must be one of SLCAN's Y rates: 500000,",
            ),
            ("slcan:/dev/x?data_bitrate=", "data_bitrate \"\""),
            ("slcan:/dev/x?fd=1&fd=1", "unknown option \"fd=1\""),
        ] {
            let err = bad.parse::<BusUrl>().unwrap_err().to_string();
            assert!(err.contains(want), "{bad}: {err}");
        }
    }

    #[test]
    fn slcan_listen_only_is_an_option() {
        let u = url("slcan:/dev/x?listen_only=1&bitrate=125000");
        assert_eq!(u.to_string(), "slcan:/dev/x?bitrate=125000&listen_only=1");
        assert_eq!(url(&u.to_string()), u);
        assert_eq!(
            url("slcan:/dev/x?listen_only=1").to_string(),
            "slcan:/dev/x?listen_only=1"
        );
        let err = "slcan:/dev/x?listen_only=yes"
            .parse::<BusUrl>()
            .unwrap_err();
        assert!(
            err.to_string()
                .contains("listen_only=\"yes\" must be 0 or 1"),
            "{err}"
        );
    }

    #[test]
    fn join_urls_parse_and_print_back() {
        for (text, full) in [
            (
                "cannelloni://10.0.0.2:20000?listen=0.0.0.0:20001",
                "cannelloni://10.0.0.2:20000?listen=0.0.0.0:20001",
            ),
            ("cannelloni://peer", "cannelloni://peer:20000"),
            ("cannelloni+tcp://[::1]:7", "cannelloni+tcp://[::1]:7"),
            (
                "cannelloni+tcp://0.0.0.0:20000?role=server",
                "cannelloni+tcp://0.0.0.0:20000?role=server",
            ),
            ("cannelloni+tcp://h:1?role=client", "cannelloni+tcp://h:1"),
            ("mqtt://broker/bench/a", "mqtt://broker:1883/bench/a"),
            ("mqtts://broker:9/x/", "mqtts://broker:9/x"),
        ] {
            let u = url(text);
            assert_eq!(u.to_string(), full, "{text}");
            assert_eq!(url(full), u);
        }
        assert_eq!(
            url("cannelloni://h:5?listen=127.0.0.1:6"),
            BusUrl::Cannelloni {
                transport: CannelloniTransport::Udp,
                host: "h".into(),
                port: 5,
                listen: Some(("127.0.0.1".into(), 6)),
            }
        );
        assert_eq!(
            url("mqtt://b:1/p/q"),
            BusUrl::Mqtt {
                host: "b".into(),
                port: 1,
                prefix: "p/q".into(),
                tls: false
            }
        );
    }

    #[test]
    fn bad_urls_name_the_url_and_what_is_wrong() {
        for (bad, want) in [
            ("socketcand://[::1/x", "unclosed ["),
            (
                "socketcand://[::1]x/x",
                "expected :PORT or nothing after ], got \"x\"",
            ),
            ("socketcand://h:0/x", "port \"0\" must be a number 1..65535"),
            ("socketcand://h:99999/x", "port \"99999\" must be a number"),
            ("socketcand://h:+5/x", "port \"+5\""),
            ("socketcand://h:/x", "port \"\""),
            ("socketcand://:1/x", "has no host"),
            ("socketcand://h:1/a b", "channel \"a b\" must be one name"),
            ("socketcand://h:1/a/b", "channel \"a/b\""),
            (
                "socketcand:h",
                "expected socketcand://HOST[:PORT][/CHANNEL]",
            ),
            ("socketcan:", "interface \"\" must be 1..15"),
            ("socketcan:averyveryverylongname", "must be 1..15"),
            ("slcan:", "has no device"),
            ("slcan:/dev/x@fast", "baud rate \"fast\""),
            ("slcan:/dev/x?bitrate=0", "bitrate \"0\""),
            ("slcan:/dev/x?speed=1", "unknown option \"speed=1\""),
            (
                "tcp://x",
                "unknown backend \"tcp\": expected socketcand://HOST[:PORT][/CHANNEL], socketcan:IFACE, slcan:DEVICE[@BAUD][?bitrate=N&listen_only=1&fd=1&data_bitrate=N], cannelloni://PEER:PORT[?listen=HOST:PORT], cannelloni+tcp://HOST:PORT[?role=server], mqtt://BROKER[:PORT]/TOPIC-PREFIX or mqtts://BROKER[:PORT]/TOPIC-PREFIX",
            ),
            ("", "unknown backend \"\""),
            ("cannelloni://h:0", "port \"0\""),
            ("cannelloni://:20000", "has no host"),
            ("cannelloni://h:1?listen=x:y", "port \"y\""),
            (
                "cannelloni://h:1?role=server",
                "unknown option \"role=server\"",
            ),
            (
                "cannelloni+tcp://h:1?listen=h:2",
                "unknown option \"listen=h:2\"",
            ),
            ("cannelloni+tcp://h:1?role=boss", "role=client|server"),
            ("mqtt://broker", "topic prefix \"\""),
            ("mqtt://broker/a//b", "topic prefix \"a//b\""),
            ("mqtt://broker/a/#", "without +, #"),
            ("mqtt://broker/a+b", "without +, #"),
            ("mqtt://user:secret@broker/a", "$BUSLAB_MQTT_PASSWORD"),
            ("mqtt://broker/a?password=x", "never"),
            ("vcan0", "unknown backend \"\""),
        ] {
            let err = bad.parse::<BusUrl>().unwrap_err();
            assert_eq!(err.url, bad);
            let text = err.to_string();
            assert!(
                text.starts_with(&format!("bus URL {bad:?}: ")) && text.contains(want),
                "{bad}: {text}"
            );
        }
    }
}
