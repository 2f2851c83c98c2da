//! MQTT (`mqtt://BROKER[:PORT]/PREFIX`): buses joined through a broker, with rumqttc.
//!
//! | topic | what |
//! |---|---|
//! | `PREFIX/frames` | envelopes ([`buslab_join::Envelope`]) from every member, QoS 0 |
//! | `PREFIX/status/ORIGIN` | `online` (retained) while the member is connected; the broker publishes `offline` (its last will, retained) when it goes without saying goodbye, and the member says it when it leaves |
//! | `PREFIX/stats/ORIGIN` | the member's [`JoinReport`] as JSON (retained), twice a second when it changed |
//!
//! Frames are batched for up to [`buslab_join::BATCH_INTERVAL_US`]; a batch that cannot be
//! published now (no connection, the client's queue full) is dropped and counted as unsent:
//! its sequence numbers are spent, so every receiver counts the frames as lost. The user name
//! and password are [`Credentials`] in [`crate::OpenOptions`] (the `buslab` binary takes them
//! from its configuration: `[mqtt]` in `buslab.toml` or the environment), never the URL.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, RecvTimeoutError};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use buslab_bus::BusError;
use buslab_join::{Accepted, Batcher, Envelope, JoinReport, MAX_ENVELOPE, Stamped};
use rumqttc::{Client, ConnectionError, Event, LastWill, MqttOptions, Packet, QoS};

use crate::join::{Accounting, Inbound, JoinBus, Shared, new_origin, wall_us};

/// A user name and password for the broker, and where they came from (the broker's refusal
/// names it). `Debug` does not show the password.
#[derive(Clone, PartialEq, Eq)]
pub struct Credentials {
    pub username: String,
    password: String,
    /// Where they were read, as the user can find it (`buslab.toml:4`, an environment
    /// variable).
    pub from: String,
}

impl Credentials {
    pub fn new(
        username: impl Into<String>,
        password: impl Into<String>,
        from: impl Into<String>,
    ) -> Self {
        Self {
            username: username.into(),
            password: password.into(),
            from: from.into(),
        }
    }
}

impl std::fmt::Debug for Credentials {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Credentials")
            .field("username", &self.username)
            .field("password", &"********")
            .field("from", &self.from)
            .finish()
    }
}

/// Where credentials come from, for the message when none were given.
const CREDENTIALS_HELP: &str = "set username and password under [mqtt] in buslab.toml, or $BUSLAB_MQTT_USERNAME and $BUSLAB_MQTT_PASSWORD (docs/config.md)";

/// How often the statistics are republished when they changed.
const STATS_INTERVAL: Duration = Duration::from_millis(500);
/// How often the idle publisher looks whether the bus is closing.
const CLOSING_POLL: Duration = Duration::from_millis(50);
/// Requests (publications) waiting for rumqttc's event loop at most.
const REQUESTS: usize = 1024;

/// Where a member of a join publishes.
#[derive(Clone, Debug)]
struct Topics {
    frames: String,
    status: String,
    stats: String,
}

impl Topics {
    fn new(prefix: &str, origin: u64) -> Self {
        Self {
            frames: format!("{prefix}/frames"),
            status: format!("{prefix}/status/{origin:016x}"),
            stats: format!("{prefix}/stats/{origin:016x}"),
        }
    }
}

/// Why the broker cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum MqttError {
    #[error("{0}")]
    Connection(Box<ConnectionError>),
    /// The broker refused the user name and password, or their absence.
    #[error("the broker refused {who}: {why}")]
    Refused { who: String, why: String },
    #[error("no answer from the broker within {0:?}")]
    Timeout(Duration),
    #[error("mqtts:// needs buslab built with the `mqtt-tls` feature")]
    NoTls,
    #[error("TLS: {0}")]
    Tls(String),
    #[error("the MQTT client stopped")]
    Stopped,
}

/// Where the broker is and how to log in.
#[derive(Clone, Copy, Debug)]
pub struct Broker<'a> {
    pub host: &'a str,
    pub port: u16,
    pub tls: bool,
    pub credentials: Option<&'a Credentials>,
}

/// The connection error, told with the credentials' origin when the broker refused them.
fn connection_error(e: ConnectionError, credentials: Option<&Credentials>) -> MqttError {
    use rumqttc::ConnectReturnCode as Code;
    let ConnectionError::ConnectionRefused(
        code @ (Code::BadUserNamePassword | Code::NotAuthorized),
    ) = e
    else {
        return e.into();
    };
    let what = match code {
        Code::BadUserNamePassword => "bad user name or password",
        _ => "not authorized",
    };
    match credentials {
        Some(c) => MqttError::Refused {
            who: format!("user {:?} (from {})", c.username, c.from),
            why: what.to_string(),
        },
        None => MqttError::Refused {
            who: "a connection without user name and password".into(),
            why: format!("{what}; {CREDENTIALS_HELP}"),
        },
    }
}

fn options(client_id: String, broker: &Broker<'_>) -> Result<MqttOptions, MqttError> {
    let (host, port, tls) = (broker.host, broker.port, broker.tls);
    let mut o = MqttOptions::new(client_id, host, port);
    o.set_keep_alive(Duration::from_secs(5))
        .set_clean_session(true)
        .set_max_packet_size(MAX_ENVELOPE + 1024, MAX_ENVELOPE + 1024);
    if let Some(c) = broker.credentials {
        o.set_credentials(c.username.clone(), c.password.clone());
    }
    if tls {
        #[cfg(feature = "mqtt-tls")]
        o.set_transport(rumqttc::Transport::tls_with_config(tls_config()?));
        #[cfg(not(feature = "mqtt-tls"))]
        return Err(MqttError::NoTls);
    }
    Ok(o)
}

/// rustls with ring and the platform's certificates (or `$SSL_CERT_FILE`'s, as
/// rustls-native-certs reads it).
#[cfg(feature = "mqtt-tls")]
fn tls_config() -> Result<rumqttc::TlsConfiguration, MqttError> {
    let found = rustls_native_certs::load_native_certs();
    let mut roots = rustls::RootCertStore::empty();
    let (added, _) = roots.add_parsable_certificates(found.certs);
    if added == 0 {
        let why = found
            .errors
            .first()
            .map_or_else(|| "none found".to_string(), ToString::to_string);
        return Err(MqttError::Tls(format!(
            "no CA certificate to check the broker with ({why}); set $SSL_CERT_FILE to a PEM file"
        )));
    }
    let provider = std::sync::Arc::new(rustls::crypto::ring::default_provider());
    let config = rustls::ClientConfig::builder_with_provider(provider)
        .with_safe_default_protocol_versions()
        .map_err(|e| MqttError::Tls(e.to_string()))?
        .with_root_certificates(roots)
        .with_no_client_auth();
    Ok(config.into())
}

/// Stops the member when the bus is dropped: publishes what is queued, says `offline`,
/// disconnects.
struct Leave {
    client: Client,
    topics: Topics,
    closing: Arc<AtomicBool>,
    publisher: Option<std::thread::JoinHandle<()>>,
    events: Option<std::thread::JoinHandle<()>>,
}

impl Drop for Leave {
    fn drop(&mut self) {
        self.closing.store(true, Ordering::SeqCst);
        if let Some(t) = self.publisher.take() {
            let _ = t.join();
        }
        let _ = self
            .client
            .try_publish(&self.topics.status, QoS::AtLeastOnce, true, "offline");
        let _ = self.client.try_disconnect();
        // Until the disconnection went out (or the connection broke): what was published
        // before is on its way to the broker.
        if let Some(t) = self.events.take() {
            let _ = t.join();
        }
    }
}

/// Joins the broker's `prefix`: returns once subscribed, so no frame published after it is
/// missed.
pub fn open(
    url: String,
    broker: Broker<'_>,
    prefix: &str,
    connect_timeout: Duration,
) -> Result<JoinBus, MqttError> {
    let origin = new_origin();
    let topics = Topics::new(prefix, origin);
    let mut o = options(format!("buslab-{origin:016x}"), &broker)?;
    o.set_last_will(LastWill::new(
        &topics.status,
        "offline",
        QoS::AtLeastOnce,
        true,
    ));
    let (client, mut connection) = Client::new(o, REQUESTS);
    let shared: Shared = Arc::new(Mutex::new(Accounting::new(origin)));
    let ((out_tx, outbox), (inbox_tx, inbox)) = JoinBus::queues();
    let connected = Arc::new(AtomicBool::new(false));
    let closing = Arc::new(AtomicBool::new(false));
    let (ready_tx, ready) = mpsc::channel::<Result<(), MqttError>>();

    // The event loop: connection, subscription, incoming envelopes.
    let ev_client = client.clone();
    let ev_topics = topics.clone();
    let ev_connected = connected.clone();
    let ev_shared = shared.clone();
    let ev_url = url.clone();
    let ev_closing = closing.clone();
    let ev_credentials = broker.credentials.cloned();
    let events = std::thread::Builder::new()
        .name("mqtt-events".into())
        .spawn(move || {
            let mut ready_tx = Some(ready_tx);
            let mut said_down = false;
            loop {
                let event = match connection.recv() {
                    Ok(event) => event,
                    // Every client handle is gone: the bus was dropped.
                    Err(_) => return,
                };
                match event {
                    Ok(Event::Outgoing(rumqttc::Outgoing::Disconnect)) => return,
                    Ok(Event::Incoming(Packet::ConnAck(_))) => {
                        // A clean session: subscribe again after each connection.
                        let _ = ev_client.try_subscribe(&ev_topics.frames, QoS::AtMostOnce);
                        let _ = ev_client.try_publish(
                            &ev_topics.status,
                            QoS::AtLeastOnce,
                            true,
                            "online",
                        );
                    }
                    Ok(Event::Incoming(Packet::SubAck(_))) => {
                        ev_connected.store(true, Ordering::SeqCst);
                        if said_down {
                            tracing::info!("{ev_url}: connected again");
                            said_down = false;
                        }
                        if let Some(tx) = ready_tx.take() {
                            let _ = tx.send(Ok(()));
                        }
                    }
                    Ok(Event::Incoming(Packet::Publish(p))) if p.topic == ev_topics.frames => {
                        let accepted = match Envelope::decode(&p.payload) {
                            Ok(e) => ev_shared.lock().map(|mut a| a.tracker.accept(e)).ok(),
                            Err(e) => {
                                tracing::debug!("{ev_url}: not an envelope: {e}");
                                if let Ok(mut a) = ev_shared.lock() {
                                    a.report.garbage += 1;
                                }
                                None
                            }
                        };
                        if let Some(Accepted::Frames(frames)) = accepted {
                            for f in frames {
                                if inbox_tx.send(Inbound::Frame(f.frame)).is_err() {
                                    return;
                                }
                            }
                        }
                    }
                    Ok(_) => {}
                    Err(e) => {
                        let e = connection_error(e, ev_credentials.as_ref());
                        ev_connected.store(false, Ordering::SeqCst);
                        if let Some(tx) = ready_tx.take() {
                            let _ = tx.send(Err(e));
                            return;
                        }
                        if ev_closing.load(Ordering::SeqCst) {
                            return;
                        }
                        if !said_down {
                            tracing::warn!(
                                "{ev_url}: broker unreachable ({e}); frames sent meanwhile are dropped and counted, trying again"
                            );
                            said_down = true;
                        }
                        // rumqttc reconnects on the next poll; not in a tight loop.
                        std::thread::sleep(Duration::from_millis(100));
                    }
                }
            }
        })
        .map_err(|_| MqttError::Stopped)?;
    match ready.recv_timeout(connect_timeout + Duration::from_secs(1)) {
        Ok(Ok(())) => {}
        Ok(Err(e)) => return Err(e),
        Err(RecvTimeoutError::Timeout) => return Err(MqttError::Timeout(connect_timeout)),
        Err(RecvTimeoutError::Disconnected) => return Err(MqttError::Stopped),
    }
    tracing::info!(
        "{url}: joined as {origin:016x} (frames on {}, status on {})",
        topics.frames,
        topics.status
    );

    // The publisher: batches, statistics.
    let pub_client = client.clone();
    let pub_topics = topics.clone();
    let pub_shared = shared.clone();
    let pub_closing = closing.clone();
    let publisher = std::thread::Builder::new()
        .name("mqtt-publish".into())
        .spawn(move || {
            let start = Instant::now();
            let now_us = || start.elapsed().as_micros() as u64;
            let mut batcher = Batcher::new(origin);
            let mut stats_due = Instant::now();
            let mut last_stats: Option<JoinReport> = None;
            let publish = |batcher: &mut Batcher| {
                let Some(envelope) = batcher.seal(wall_us()) else {
                    return;
                };
                let n = envelope.frames.len() as u64;
                let sent = connected.load(Ordering::SeqCst)
                    && envelope.encode().is_ok_and(|bytes| {
                        pub_client
                            .try_publish(&pub_topics.frames, QoS::AtMostOnce, false, bytes)
                            .is_ok()
                    });
                if let Ok(mut a) = pub_shared.lock() {
                    if sent {
                        a.report.sent += n;
                    } else {
                        a.report.unsent += n;
                    }
                }
            };
            loop {
                let wait = batcher
                    .deadline()
                    .map(|d| Duration::from_micros(d.saturating_sub(now_us())))
                    .unwrap_or(CLOSING_POLL)
                    .min(CLOSING_POLL)
                    .min(stats_due.saturating_duration_since(Instant::now()));
                match outbox.recv_timeout(wait) {
                    Ok(frame) => {
                        let stamped = Stamped {
                            bus_us: wall_us(),
                            frame,
                        };
                        if batcher.push(stamped, now_us()) {
                            publish(&mut batcher);
                        }
                    }
                    Err(RecvTimeoutError::Timeout) if !pub_closing.load(Ordering::SeqCst) => {}
                    Err(_) => {
                        publish(&mut batcher);
                        publish_stats(&pub_client, &pub_topics, &pub_shared, &mut last_stats);
                        return;
                    }
                }
                if batcher.deadline().is_some_and(|d| d <= now_us()) {
                    publish(&mut batcher);
                }
                if Instant::now() >= stats_due {
                    publish_stats(&pub_client, &pub_topics, &pub_shared, &mut last_stats);
                    stats_due = Instant::now() + STATS_INTERVAL;
                }
            }
        })
        .map_err(|_| MqttError::Stopped)?;
    Ok(JoinBus::new(
        url,
        out_tx,
        inbox,
        shared,
        Box::new(Leave {
            client,
            topics,
            closing,
            publisher: Some(publisher),
            events: Some(events),
        }),
    ))
}

/// The report on `PREFIX/stats/ORIGIN` (retained) if it changed.
fn publish_stats(client: &Client, topics: &Topics, shared: &Shared, last: &mut Option<JoinReport>) {
    let Ok(report) = shared.lock().map(|a| a.snapshot()) else {
        return;
    };
    if last.as_ref() == Some(&report) {
        return;
    }
    if let Ok(json) = serde_json::to_vec(&report)
        && client
            .try_publish(&topics.stats, QoS::AtLeastOnce, true, json)
            .is_ok()
    {
        *last = Some(report);
    }
}

/// One member of a join as the broker keeps it: its last status and statistics.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Member {
    pub origin: String,
    /// `online`/`offline` from its status topic, if any.
    pub online: Option<bool>,
    pub report: Option<JoinReport>,
}

/// Every member's retained status and statistics under `prefix`: subscribes, then waits for
/// its own probe to come back (the broker sends retained messages before it).
pub fn members(
    broker: Broker<'_>,
    prefix: &str,
    timeout: Duration,
) -> Result<Vec<Member>, MqttError> {
    let me = new_origin();
    let probe = format!("{prefix}/probe/{me:016x}");
    let (client, mut connection) =
        Client::new(options(format!("buslab-status-{me:016x}"), &broker)?, 64);
    let deadline = Instant::now() + timeout;
    let mut members: std::collections::BTreeMap<String, Member> = Default::default();
    let status = format!("{prefix}/status/");
    let stats = format!("{prefix}/stats/");
    let mut subscribed = 0;
    loop {
        let left = deadline.saturating_duration_since(Instant::now());
        let event = match connection.recv_timeout(left) {
            Ok(Ok(e)) => e,
            Ok(Err(e)) => return Err(connection_error(e, broker.credentials)),
            Err(_) => return Err(MqttError::Timeout(timeout)),
        };
        match event {
            Event::Incoming(Packet::ConnAck(_)) => {
                let _ = client.try_subscribe(format!("{status}+"), QoS::AtLeastOnce);
                let _ = client.try_subscribe(format!("{stats}+"), QoS::AtLeastOnce);
                let _ = client.try_subscribe(&probe, QoS::AtLeastOnce);
            }
            Event::Incoming(Packet::SubAck(_)) => {
                subscribed += 1;
                if subscribed == 3 {
                    let _ = client.try_publish(&probe, QoS::AtLeastOnce, false, "probe");
                }
            }
            Event::Incoming(Packet::Publish(p)) if p.topic == probe => break,
            Event::Incoming(Packet::Publish(p)) => {
                let (origin, is_status) =
                    match (p.topic.strip_prefix(&status), p.topic.strip_prefix(&stats)) {
                        (Some(o), _) => (o, true),
                        (_, Some(o)) => (o, false),
                        _ => continue,
                    };
                let m = members.entry(origin.to_string()).or_insert_with(|| Member {
                    origin: origin.to_string(),
                    online: None,
                    report: None,
                });
                if is_status {
                    m.online = Some(&p.payload[..] == b"online");
                } else {
                    m.report = serde_json::from_slice(&p.payload).ok();
                }
            }
            _ => {}
        }
    }
    let _ = client.try_disconnect();
    Ok(members.into_values().collect())
}

impl From<ConnectionError> for MqttError {
    fn from(e: ConnectionError) -> Self {
        MqttError::Connection(Box::new(e))
    }
}

impl From<MqttError> for BusError {
    fn from(e: MqttError) -> Self {
        BusError::Other(Box::new(e))
    }
}
