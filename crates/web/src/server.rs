//! The listener: a bounded number of connections, each served by hyper with limits on how
//! large a request head may be and how long a client may take (crate::limits).

use std::net::SocketAddr;
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::thread::JoinHandle;
use std::time::Duration;

use buslab_backends::DynBus;
use hyper_util::rt::{TokioIo, TokioTimer};
use hyper_util::service::TowerToHyperService;
use tokio::sync::{Semaphore, oneshot};

use crate::app::App;
use crate::guard::{HostGuard, SECURITY_HEADERS};
use crate::hub::BusSide;
use crate::limits::{StallGuard, Timeouts};
use crate::routes::router;
use crate::{WebConfig, WebError, check_token};

/// The largest request head read (hyper's smallest allowed buffer is 8 KiB).
const MAX_HEAD: usize = 16 * 1024;

/// The kernel's send buffer of each connection (it doubles it for its bookkeeping): what a
/// viewer that stops reading can hold besides hyper's buffer and one update. Left to
/// itself the kernel grows it to `tcp_wmem`'s maximum (4 MiB here) per connection.
const SEND_BUFFER: usize = 64 * 1024;

/// How long a refused connection gets to take its 503.
const REFUSAL_TIME: Duration = Duration::from_secs(2);

/// The answer to a connection over the limit, with the headers every answer carries.
fn busy() -> Vec<u8> {
    const REASON: &str = "too many connections: try again later\n";
    let mut head = String::from(
        "HTTP/1.1 503 Service Unavailable\r\ncontent-type: text/plain; charset=utf-8\r\n\
         connection: close\r\n",
    );
    for (name, value) in SECURITY_HEADERS {
        head.push_str(&format!("{name}: {value}\r\n"));
    }
    head.push_str(&format!("content-length: {}\r\n\r\n{REASON}", REASON.len()));
    head.into_bytes()
}

/// A running web server. Dropping it (or [`WebServer::stop`]) closes every connection and
/// leaves the bus.
pub struct WebServer {
    addr: SocketAddr,
    token: Option<String>,
    bus: Option<BusSide>,
    shutdown: Option<oneshot::Sender<()>>,
    thread: Option<JoinHandle<()>>,
}

impl WebServer {
    /// Listens on `config.listen` and serves `bus` until stopped.
    pub fn start(bus: DynBus, config: WebConfig) -> Result<Self, WebError> {
        if let Some(token) = &config.token {
            check_token(token)?;
        }
        if config.max_connections == 0 {
            return Err(WebError::NoConnections);
        }
        let hosts = Arc::new(HostGuard::new(&config.allowed_hosts)?);
        if config.timeouts.request.is_zero() || config.timeouts.stalled_write.is_zero() {
            return Err(WebError::NoTime);
        }
        let listener =
            std::net::TcpListener::bind(config.listen).map_err(|source| WebError::Listen {
                addr: config.listen,
                source,
            })?;
        let addr = listener.local_addr().map_err(|source| WebError::Listen {
            addr: config.listen,
            source,
        })?;
        listener
            .set_nonblocking(true)
            .map_err(|source| WebError::Listen { addr, source })?;
        let side = BusSide::start(bus, &config).map_err(WebError::Threads)?;
        let app = App {
            hub: side.hub.clone(),
            sender: side.sender.clone(),
            token: config.token.clone().map(Arc::from),
            hosts,
            timeouts: config.timeouts,
            join: config.join.clone(),
        };
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(2)
            .thread_name("web")
            .enable_all()
            .build()
            .map_err(WebError::Threads)?;
        let (shutdown, stopped) = oneshot::channel();
        let max = config.max_connections;
        let thread = std::thread::Builder::new()
            .name("web-accept".into())
            .spawn(move || {
                runtime.block_on(async move {
                    match tokio::net::TcpListener::from_std(listener) {
                        Ok(listener) => accept(listener, app, max, stopped).await,
                        Err(e) => tracing::warn!("cannot listen on {addr}: {e}"),
                    }
                });
                // Open connections (live dashboards) end with the runtime.
                runtime.shutdown_background();
            })
            .map_err(WebError::Threads)?;
        Ok(Self {
            addr,
            token: config.token,
            bus: Some(side),
            shutdown: Some(shutdown),
            thread: Some(thread),
        })
    }

    /// Where it listens (the port chosen when asked for port 0).
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// `http://ADDR/`.
    pub fn url(&self) -> String {
        format!("http://{}/", self.addr)
    }

    /// The write token, if writes are allowed.
    pub fn token(&self) -> Option<&str> {
        self.token.as_deref()
    }

    /// Why the bus stopped, once it did (the pages keep showing the last state).
    pub fn bus_failure(&self) -> Option<String> {
        self.bus.as_ref().and_then(|b| b.hub.failure())
    }

    /// Stops serving and leaves the bus.
    pub fn stop(mut self) {
        self.shut();
    }

    fn shut(&mut self) {
        if let Some(s) = self.shutdown.take() {
            let _ = s.send(());
        }
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
        drop(self.bus.take());
    }
}

impl Drop for WebServer {
    fn drop(&mut self) {
        self.shut();
    }
}

async fn accept(
    listener: tokio::net::TcpListener,
    app: App,
    max: usize,
    mut stopped: oneshot::Receiver<()>,
) {
    let limit = Arc::new(Semaphore::new(max));
    let refusals = Arc::new(Semaphore::new(max));
    let hub = app.hub.clone();
    let Timeouts {
        request,
        stalled_write,
    } = app.timeouts;
    let router = router(app);
    loop {
        let (stream, peer) = tokio::select! {
            _ = &mut stopped => return,
            accepted = listener.accept() => match accepted {
                Ok(pair) => pair,
                Err(e) => {
                    // Out of file descriptors, most likely: let connections finish.
                    tracing::warn!("cannot accept a connection: {e}");
                    tokio::time::sleep(Duration::from_millis(50)).await;
                    continue;
                }
            },
        };
        let Ok(permit) = limit.clone().try_acquire_owned() else {
            hub.refused.fetch_add(1, Ordering::Relaxed);
            // Said politely while there is room for that; dropped (closed) otherwise.
            if let Ok(slot) = refusals.clone().try_acquire_owned() {
                tokio::spawn(async move {
                    refuse(stream).await;
                    drop(slot);
                });
            }
            continue;
        };
        if let Err(e) = socket2::SockRef::from(&stream).set_send_buffer_size(SEND_BUFFER) {
            tracing::debug!("connection from {peer}: cannot bound its send buffer: {e}");
        }
        let service = TowerToHyperService::new(router.clone());
        tokio::spawn(async move {
            // The header timer also runs while a kept-alive connection waits for its next
            // request: an idle connection is closed after it too.
            let served = hyper::server::conn::http1::Builder::new()
                .timer(TokioTimer::new())
                .header_read_timeout(request)
                .max_buf_size(MAX_HEAD)
                .serve_connection(
                    TokioIo::new(StallGuard::new(stream, stalled_write)),
                    service,
                )
                .await;
            if let Err(e) = served {
                tracing::debug!("connection from {peer}: {e}");
            }
            drop(permit);
        });
    }
}

/// Answers 503 and closes; what the client sent is read first so the close does not reset the
/// connection before the answer is read.
async fn refuse(mut stream: tokio::net::TcpStream) {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let _ = tokio::time::timeout(REFUSAL_TIME, async {
        stream.write_all(&busy()).await?;
        stream.shutdown().await?;
        let mut sink = [0u8; 4096];
        while stream.read(&mut sink).await? > 0 {}
        Ok::<(), std::io::Error>(())
    })
    .await;
}
