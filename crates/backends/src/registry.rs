//! The backends, keyed by URL scheme: how each reads its URLs and opens a bus.

use std::io;
use std::time::Duration;

use buslab_bus::{AcceptanceFilter, ControllerMode, ControllerPart, ControllerSettings};
use buslab_slcan::AcceptanceAnswer;
use buslab_socketcand::{ClientError, ClientOptions, SocketcandBus};

use crate::DynBus;
use crate::controller::{Accepting, ControllerReport, Outcome};
use crate::url::{self, BusUrl, DEFAULT_NAME, UrlError, UrlProblem, parse_slcan, parse_socketcan};
use std::str::FromStr;

/// Deadlines for opening a bus, what to ask of this client's controller, and how to log in to
/// an MQTT broker.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct OpenOptions {
    /// How long to wait for a connection.
    pub connect_timeout: Duration,
    /// How long to wait for each answer of the server or device.
    pub reply_timeout: Duration,
    /// The controller configuration to apply where the bus has the setting (see
    /// [`crate::controller`]); empty by default: the bus or adapter as it is.
    pub controller: ControllerSettings,
    /// The user name and password `mqtt://` logs in with; none by default.
    pub mqtt_credentials: Option<crate::mqtt::Credentials>,
}

impl Default for OpenOptions {
    fn default() -> Self {
        let c = ClientOptions::default();
        Self {
            connect_timeout: c.connect_timeout,
            reply_timeout: c.reply_timeout,
            controller: ControllerSettings::default(),
            mqtt_credentials: None,
        }
    }
}

/// An open bus and what became of the controller settings asked for.
pub struct Opened {
    pub bus: DynBus,
    pub controller: ControllerReport,
}

/// A backend's way to open a bus.
pub type OpenFn = fn(&BusUrl, &OpenOptions) -> Result<Opened, OpenError>;

/// Why a bus could not be opened.
#[derive(Debug, thiserror::Error)]
pub enum OpenError {
    #[error(transparent)]
    Url(#[from] UrlError),
    #[error(
        "{url}: the {scheme} backend is not available yet (use {})",
        available_syntaxes()
    )]
    NotAvailable { url: String, scheme: &'static str },
    /// The reason's text is part of the message (with a hint when nobody listens).
    #[error("cannot join {url}: {reason}{}", hint(reason))]
    Connect { url: String, reason: ClientError },
    /// A SocketCAN interface that cannot be opened, with what to do about it. The reason's
    /// text is part of the message, before the hint (so it is not also the error's source,
    /// which a report of the causes would print a second time).
    #[error("cannot open {url}: {reason}{}", socketcan_hint(reason, interface))]
    SocketCan {
        url: String,
        interface: String,
        reason: io::Error,
    },
    /// An SLCAN adapter that cannot be opened or does not answer.
    #[error("cannot open {url}: {source}")]
    Slcan {
        url: String,
        source: buslab_slcan::SlcanError,
    },
    /// A join transport (cannelloni, MQTT) that cannot be set up: its socket, its peer, its
    /// broker.
    #[error("cannot join {url}: {reason}")]
    Join {
        url: String,
        reason: Box<dyn std::error::Error + Send + Sync>,
    },
    /// The controller settings cannot be used on this bus (a timing no command of the
    /// adapter reaches, a combination the chip refuses).
    #[error("{url}: cannot set this client's controller ({settings}): {reason}")]
    Controller {
        url: String,
        settings: ControllerSettings,
        reason: String,
    },
}

/// What to do about an interface that cannot be opened.
fn socketcan_hint(e: &io::Error, interface: &str) -> String {
    match e.raw_os_error() {
        Some(libc_enodev) if libc_enodev == ENODEV => format!(
            " (no interface {interface} on this machine: buslab's own bus, from `buslab lab` or `buslab bus serve`, is vcan0 or its socketcand://HOST:PORT/CHANNEL URL; a virtual SocketCAN interface is made as root with `ip link add dev {interface} type vcan && ip link set up {interface}`)"
        ),
        Some(no_family) if no_family == EAFNOSUPPORT => " (this kernel has no SocketCAN: load the can and can-raw modules, or use a bus served by `buslab bus serve`)".to_string(),
        _ => String::new(),
    }
}

/// Linux's errno values for the hints (the same on every Linux architecture buslab builds on).
const ENODEV: i32 = 19;
const EAFNOSUPPORT: i32 = 97;

/// What to do about a refused connection.
fn hint(reason: &ClientError) -> &'static str {
    match reason {
        ClientError::Io(e) if e.kind() == io::ErrorKind::ConnectionRefused => {
            " (nobody listens there: start a bus with `buslab bus serve` or `buslab lab`)"
        }
        _ => "",
    }
}

/// One backend.
pub struct Backend {
    /// The URL scheme, the registry's key.
    pub scheme: &'static str,
    /// The URL syntax, for help texts and errors.
    pub syntax: &'static str,
    pub description: &'static str,
    /// Reads a whole URL of this scheme.
    pub parse: fn(&str) -> Result<BusUrl, UrlError>,
    /// Opens a bus; `None` for a slot a later version fills.
    pub open: Option<OpenFn>,
}

/// Every backend, by scheme.
pub static BACKENDS: &[Backend] = &[
    Backend {
        scheme: "socketcand",
        syntax: "socketcand://HOST[:PORT][/CHANNEL]",
        description: "socketcand raw mode over TCP (buslab bus serve, buslab lab, socketcand)",
        parse: url::parse_socketcand,
        open: Some(open_socketcand),
    },
    Backend {
        scheme: "socketcan",
        syntax: "socketcan:IFACE",
        description: "a Linux SocketCAN interface (can0, vcan0, slcan0; Linux only)",
        parse: url::parse_socketcan,
        open: SOCKETCAN_OPEN,
    },
    Backend {
        scheme: "slcan",
        syntax: "slcan:DEVICE[@BAUD][?bitrate=N&listen_only=1&fd=1&data_bitrate=N]",
        description: "an SLCAN (Lawicel) serial adapter: CANable, CANUSB, `buslab slcan serve`",
        parse: url::parse_slcan,
        open: Some(open_slcan),
    },
    Backend {
        scheme: "cannelloni",
        syntax: "cannelloni://PEER:PORT[?listen=HOST:PORT]",
        description: "cannelloni over UDP: frames to the peer's port, from this side's listen address (cannelloni, another buslab)",
        parse: url::parse_cannelloni,
        open: Some(open_cannelloni),
    },
    Backend {
        scheme: "cannelloni+tcp",
        syntax: "cannelloni+tcp://HOST:PORT[?role=server]",
        description: "cannelloni over TCP: connects to HOST:PORT, or listens there for one peer with role=server (python-can's can-cannelloni connects)",
        parse: url::parse_cannelloni,
        open: Some(open_cannelloni),
    },
    Backend {
        scheme: "mqtt",
        syntax: "mqtt://BROKER[:PORT]/TOPIC-PREFIX",
        description: "buses joined through an MQTT broker (Mosquitto): numbered envelopes on PREFIX/frames, status and counters per member",
        parse: url::parse_mqtt,
        open: Some(open_mqtt),
    },
    Backend {
        scheme: "mqtts",
        syntax: "mqtts://BROKER[:PORT]/TOPIC-PREFIX",
        description: "the same over TLS (buslab built with the mqtt-tls feature)",
        parse: url::parse_mqtt,
        open: Some(open_mqtt),
    },
];

/// The backend for `scheme`.
pub fn backend(scheme: &str) -> Option<&'static Backend> {
    BACKENDS.iter().find(|b| b.scheme == scheme)
}

/// Every syntax: "A, B or C".
pub fn syntaxes() -> String {
    or_list(BACKENDS.iter().map(|b| b.syntax))
}

/// The syntaxes of the backends that can be opened.
fn available_syntaxes() -> String {
    or_list(
        BACKENDS
            .iter()
            .filter(|b| b.open.is_some())
            .map(|b| b.syntax),
    )
}

fn or_list<'a>(items: impl Iterator<Item = &'a str>) -> String {
    let items: Vec<&str> = items.collect();
    match items.split_last() {
        Some((last, rest)) if !rest.is_empty() => format!("{} or {last}", rest.join(", ")),
        Some((last, _)) => last.to_string(),
        None => String::new(),
    }
}

/// Opens the bus behind a URL (python-can's `can.Bus(interface=…, channel=…)`), with the
/// default deadlines.
pub fn open(url: &str) -> Result<DynBus, OpenError> {
    open_url(&url.parse()?, &OpenOptions::default())
}

/// Opens a parsed URL with its backend from the registry; a part of the controller settings
/// the bus cannot apply is logged as a warning.
pub fn open_url(url: &BusUrl, options: &OpenOptions) -> Result<DynBus, OpenError> {
    let opened = open_configured(url, options)?;
    for (part, why) in opened.controller.not_applied() {
        tracing::warn!("{url}: {} not applied: {why}", part.describe());
    }
    Ok(opened.bus)
}

/// Opens a parsed URL with its backend from the registry, and says what became of each part
/// of the controller settings asked for.
pub fn open_configured(url: &BusUrl, options: &OpenOptions) -> Result<Opened, OpenError> {
    let scheme = url.scheme();
    match backend(scheme).and_then(|b| b.open) {
        Some(open) => open(url, options),
        None => Err(OpenError::NotAvailable {
            url: url.to_string(),
            scheme,
        }),
    }
}

/// The bus as it is, nothing asked of its controller.
fn plain(bus: DynBus) -> Opened {
    Opened {
        bus,
        controller: ControllerReport::default(),
    }
}

/// A bus with no controller of the client's own: the filter is checked by buslab
/// ([`accepting`]), the other parts are not applied, for `why`.
fn without_controller(settings: &ControllerSettings, why: &str) -> ControllerReport {
    ControllerReport::each(settings, |part| match part {
        ControllerPart::Filter => Outcome::Applied(format!(
            "each frame checked by buslab as the configured SJA1000 would ({why})"
        )),
        _ => Outcome::NotApplied(why.to_string()),
    })
}

/// `bus` checking received frames against `filter` when one is asked.
fn accepting(bus: DynBus, filter: Option<AcceptanceFilter>) -> DynBus {
    match filter {
        Some(f) if f != AcceptanceFilter::AcceptAll => Box::new(Accepting::new(bus, f)),
        _ => bus,
    }
}

#[cfg(target_os = "linux")]
const SOCKETCAN_OPEN: Option<OpenFn> = Some(open_socketcan);
/// SocketCAN is Linux's: elsewhere the slot says "not available".
#[cfg(not(target_os = "linux"))]
const SOCKETCAN_OPEN: Option<OpenFn> = None;

/// A wrong URL kind handed to a backend's `open` (only by calling it directly).
fn wrong_kind(url: &BusUrl, expected: &'static str) -> OpenError {
    OpenError::Url(UrlError {
        url: url.to_string(),
        problem: UrlProblem::Syntax { expected },
    })
}

#[cfg(target_os = "linux")]
fn open_socketcan(url: &BusUrl, options: &OpenOptions) -> Result<Opened, OpenError> {
    let BusUrl::SocketCan { interface } = url else {
        return Err(wrong_kind(url, "socketcan:IFACE"));
    };
    let socketcan_error = |reason| OpenError::SocketCan {
        url: url.to_string(),
        interface: interface.clone(),
        reason,
    };
    let mut bus = crate::socketcan::SocketCanBus::open(interface).map_err(socketcan_error)?;
    tracing::info!("opened {url}");
    let settings = options.controller;
    if let Some(filter) = settings.filter {
        // The ID part in the kernel (fewer wake-ups); the rest is checked by `Accepting`.
        buslab_bus::CanBus::set_filters(&mut bus, &filter.id_cover())
            .map_err(|e| socketcan_error(std::io::Error::other(e.to_string())))?;
    }
    let netlink = |what: String| {
        Outcome::NotApplied(format!(
            "a SocketCAN interface's {what} is set through netlink, which buslab does not use:              `ip link set {interface} down && ip link set {interface} type can {} && ip link set {interface} up` (as root)",
            match what.as_str() {
                "bit rate" => format!("bitrate {}", settings.timing.map_or(0, |t| t.bitrate())),
                _ => "listen-only on".to_string(),
            }
        ))
    };
    let controller = ControllerReport::each(&settings, |part| match part {
        ControllerPart::Filter => Outcome::Applied(
            "kernel filters on the ID, then each frame checked by buslab as the SJA1000 would"
                .into(),
        ),
        ControllerPart::Timing => netlink("bit rate".into()),
        ControllerPart::Mode if settings.mode == Some(ControllerMode::ListenOnly) => {
            netlink("listen-only mode".into())
        }
        _ => Outcome::NotApplied(
            "a SocketCAN interface has no such setting (its driver programs the chip)".into(),
        ),
    });
    Ok(Opened {
        bus: accepting(Box::new(bus), settings.filter),
        controller,
    })
}

fn open_slcan(url: &BusUrl, options: &OpenOptions) -> Result<Opened, OpenError> {
    let BusUrl::Slcan {
        device,
        baud,
        bitrate,
        listen_only,
        fd,
        data_bitrate,
    } = url
    else {
        return Err(wrong_kind(
            url,
            "slcan:DEVICE[@BAUD][?bitrate=N&listen_only=1&fd=1&data_bitrate=N]",
        ));
    };
    let settings = options.controller;
    let asked_rate = settings.timing.map(|t| t.bitrate());
    // The URL is the more specific: its bit rate and listen-only win over the configuration's.
    let listen = settings.mode == Some(ControllerMode::ListenOnly);
    let slcan = buslab_slcan::SlcanOptions {
        baud: baud.unwrap_or(buslab_slcan::SlcanOptions::default().baud),
        bitrate: bitrate.or(asked_rate),
        listen_only: *listen_only || listen,
        reply_timeout: options.reply_timeout,
        fd: *fd,
        data_bitrate: *data_bitrate,
    };
    let acceptance = settings
        .filter
        .filter(|f| *f != AcceptanceFilter::AcceptAll)
        .map(|f| {
            let (code, mask) = f.registers();
            (u32::from_be_bytes(code), u32::from_be_bytes(mask))
        });
    let bus = buslab_slcan::SlcanBus::open_with_acceptance(device, &slcan, acceptance).map_err(
        |source| match source {
            buslab_slcan::SlcanError::Bitrate { .. } if bitrate.is_none() => {
                OpenError::Controller {
                    url: url.to_string(),
                    settings,
                    reason: source.to_string(),
                }
            }
            source => OpenError::Slcan {
                url: url.to_string(),
                source,
            },
        },
    )?;
    let answer = bus.acceptance_answer();
    let controller = ControllerReport::each(&settings, |part| {
        match part {
        ControllerPart::Timing => match (bitrate, asked_rate) {
            (Some(url_rate), Some(rate)) if *url_rate != rate => Outcome::NotApplied(format!(
                "the URL's bitrate={url_rate} wins over the configuration's {rate} bit/s"
            )),
            _ => Outcome::Applied(format!(
                "the adapter's bit rate set to {} bit/s (S/s)",
                slcan.bitrate.unwrap_or(0)
            )),
        },
        ControllerPart::Mode if listen => Outcome::Applied("the channel opened with L".into()),
        ControllerPart::Filter => Outcome::Applied(match answer {
            _ if acceptance.is_none() => "nothing to set (accept all)".into(),
            AcceptanceAnswer::Taken => {
                "acceptance code and mask sent to the adapter (M/m), and each frame checked by buslab as the configured SJA1000 would".into()
            }
            AcceptanceAnswer::Unconfirmed => {
                "acceptance code and mask sent (M/m, unconfirmed: the adapter answers no command), and each frame checked by buslab".into()
            }
            AcceptanceAnswer::Refused => {
                "the adapter refused M/m; each frame is checked by buslab as the configured SJA1000 would".into()
            }
            AcceptanceAnswer::NotSent => {
                "this adapter has no acceptance filter command (CANable's M is its silent mode); each frame is checked by buslab as the configured SJA1000 would".into()
            }
        }),
        _ => Outcome::NotApplied(
            "an SLCAN adapter has no command for it (only S/s, L and M/m)".into(),
        ),
    }
    });
    Ok(Opened {
        bus: accepting(Box::new(bus), settings.filter),
        controller,
    })
}

/// The first address `host:port` resolves to.
fn address(url: &BusUrl, host: &str, port: u16) -> Result<std::net::SocketAddr, OpenError> {
    use std::net::ToSocketAddrs;
    (host, port)
        .to_socket_addrs()
        .and_then(|mut a| {
            a.next()
                .ok_or_else(|| io::Error::other(format!("{host} has no address")))
        })
        .map_err(|e| OpenError::Join {
            url: url.to_string(),
            reason: e.into(),
        })
}

/// A joined bus has no controller of its own: the settings are refused as such.
fn joined(bus: crate::join::JoinBus, options: &OpenOptions) -> Opened {
    let settings = options.controller;
    Opened {
        bus: accepting(Box::new(bus), settings.filter),
        controller: without_controller(
            &settings,
            "a bus joined over the network has no controller of its own",
        ),
    }
}

/// Opens a join transport as its own type (a gateway sends from one thread and receives on
/// another: [`crate::join::JoinBus::sender`]).
pub fn open_join(url: &BusUrl, options: &OpenOptions) -> Result<crate::join::JoinBus, OpenError> {
    let failed = |reason: Box<dyn std::error::Error + Send + Sync>| OpenError::Join {
        url: url.to_string(),
        reason,
    };
    match url {
        BusUrl::Cannelloni {
            transport,
            host,
            port,
            listen,
        } => {
            let peer = address(url, host, *port)?;
            match transport {
                url::CannelloniTransport::Udp => {
                    let listen = match listen {
                        Some((h, p)) => address(url, h, *p)?,
                        None if peer.is_ipv6() => (std::net::Ipv6Addr::UNSPECIFIED, *port).into(),
                        None => (std::net::Ipv4Addr::UNSPECIFIED, *port).into(),
                    };
                    crate::cannelloni::open_udp(url.to_string(), peer, listen)
                }
                url::CannelloniTransport::TcpClient => crate::cannelloni::open_tcp_client(
                    url.to_string(),
                    peer,
                    options.connect_timeout,
                    options.reply_timeout,
                ),
                url::CannelloniTransport::TcpServer => {
                    crate::cannelloni::open_tcp_server(url.to_string(), peer)
                }
            }
            .map_err(|e| failed(e.into()))
        }
        BusUrl::Mqtt {
            host,
            port,
            prefix,
            tls,
        } => crate::mqtt::open(
            url.to_string(),
            crate::mqtt::Broker {
                host,
                port: *port,
                tls: *tls,
                credentials: options.mqtt_credentials.as_ref(),
            },
            prefix,
            options.connect_timeout,
        )
        .map_err(|e| failed(e.into())),
        _ => Err(wrong_kind(
            url,
            "cannelloni://PEER:PORT, cannelloni+tcp://HOST:PORT or mqtt://BROKER/PREFIX",
        )),
    }
}

fn open_cannelloni(url: &BusUrl, options: &OpenOptions) -> Result<Opened, OpenError> {
    Ok(joined(open_join(url, options)?, options))
}

fn open_mqtt(url: &BusUrl, options: &OpenOptions) -> Result<Opened, OpenError> {
    Ok(joined(open_join(url, options)?, options))
}

/// Connects, turns buslab's extensions on when the server has them, and programs this
/// client's own SJA1000 with the controller settings.
fn open_socketcand(url: &BusUrl, options: &OpenOptions) -> Result<Opened, OpenError> {
    let BusUrl::Socketcand {
        host,
        port,
        channel,
    } = url
    else {
        return Err(wrong_kind(url, "socketcand://HOST[:PORT][/CHANNEL]"));
    };
    let connect = |reason| OpenError::Connect {
        url: url.to_string(),
        reason,
    };
    let client = ClientOptions {
        connect_timeout: options.connect_timeout,
        reply_timeout: options.reply_timeout,
    };
    let mut bus =
        SocketcandBus::connect_with((host.as_str(), *port), channel, client).map_err(connect)?;
    let extensions = bus.enable_extensions().map_err(connect)?;
    tracing::info!(
        "joined {url}{}",
        if extensions {
            " (a buslab bus)"
        } else {
            " (a plain socketcand: no node status, registers or send confirmation)"
        }
    );
    let settings = options.controller;
    if settings.is_empty() {
        return Ok(plain(Box::new(bus)));
    }
    if !extensions {
        let controller = without_controller(
            &settings,
            "a plain socketcand server: its interface is set up on the server (ip link)",
        );
        return Ok(Opened {
            bus: accepting(Box::new(bus), settings.filter),
            controller,
        });
    }
    match bus.configure(&settings) {
        Ok(()) => Ok(Opened {
            bus: Box::new(bus),
            controller: ControllerReport::each(&settings, |_| {
                Outcome::Applied("this client's own SJA1000 on the virtual bus".into())
            }),
        }),
        Err(ClientError::Server(text)) if text.contains("unknown command") => {
            let controller = without_controller(
                &settings,
                "this buslab server is older and has no buslab_controller",
            );
            Ok(Opened {
                bus: accepting(Box::new(bus), settings.filter),
                controller,
            })
        }
        Err(ClientError::Server(reason)) => Err(OpenError::Controller {
            url: url.to_string(),
            settings,
            reason,
        }),
        Err(e) => Err(connect(e)),
    }
}

impl FromStr for BusUrl {
    type Err = UrlError;

    /// Finds the backend by the URL's scheme in the registry and lets it read the rest.
    fn from_str(url: &str) -> Result<Self, UrlError> {
        let scheme = url.split_once(':').map_or("", |(s, _)| s);
        match backend(scheme) {
            Some(b) => (b.parse)(url),
            None => Err(UrlError::new(
                url,
                UrlProblem::UnknownScheme {
                    scheme: scheme.to_string(),
                    expected: syntaxes(),
                },
            )),
        }
    }
}

/// A bus as a person types it on the command line, as can-utils take interface names:
///
/// | name | bus |
/// |---|---|
/// | `vcan0` | buslab's bus on this machine, [`crate::DEFAULT_URL`] (`buslab bus serve`, `buslab lab`) |
/// | a URL (`socketcand://…`, `socketcan:…`, `slcan:…`) | as it says |
/// | a path (`/dev/ttyACM0`, `./adapter`) | the SLCAN adapter there, `slcan:PATH` |
/// | any other interface name (`can0`, `vcan1`, `slcan0`) | the Linux interface, `socketcan:NAME` |
///
/// ```
/// use buslab_backends::{BusUrl, resolve};
///
/// assert_eq!(resolve("vcan0")?.to_string(), "socketcand://127.0.0.1:29536/vcan0");
/// assert_eq!(resolve("can0")?.to_string(), "socketcan:can0");
/// assert_eq!(resolve("/dev/ttyACM0")?.to_string(), "slcan:/dev/ttyACM0");
/// assert_eq!(resolve("socketcand://bench:29536/can1")?.to_string(), "socketcand://bench:29536/can1");
/// # Ok::<(), buslab_backends::UrlError>(())
/// ```
pub fn resolve(name: &str) -> Result<BusUrl, UrlError> {
    if name == DEFAULT_NAME {
        return crate::DEFAULT_URL.parse();
    }
    if name.starts_with('/') || name.starts_with("./") || name.starts_with("../") {
        return parse_slcan(&format!("slcan:{name}")).map_err(|e| UrlError::new(name, e.problem));
    }
    if name.contains(':') {
        return name.parse();
    }
    parse_socketcan(&format!("socketcan:{name}"))
        .map_err(|_| UrlError::new(name, UrlProblem::Name(name.to_string(), syntaxes())))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_interface_that_cannot_be_opened_is_named_once_with_what_to_do() {
        // `buslab dump can0` printed `No such device (os error 19)` twice: once in the
        // message and once more as its source.
        for (errno, hint) in [
            (ENODEV, "ip link add dev can0 type vcan"),
            (EAFNOSUPPORT, "this kernel has no SocketCAN"),
        ] {
            let e = OpenError::SocketCan {
                url: "socketcan:can0".into(),
                interface: "can0".into(),
                reason: io::Error::from_raw_os_error(errno),
            };
            assert!(std::error::Error::source(&e).is_none());
            let text = e.to_string();
            assert_eq!(
                text.matches(&format!("(os error {errno})")).count(),
                1,
                "{text}"
            );
            assert!(text.contains(hint), "{text}");
        }
    }
}
