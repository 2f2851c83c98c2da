//! TLS for the notifier: rustls, trusting the system's certificates (or `$SSL_CERT_FILE` /
//! `$SSL_CERT_DIR`, as OpenSSL does) or only those of `--ca-file`.

use std::io;
use std::net::TcpStream;
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

use anyhow::{Context, bail};
use rustls::pki_types::pem::PemObject;
use rustls::pki_types::{CertificateDer, ServerName};
use rustls::{ClientConfig, ClientConnection, RootCertStore, StreamOwned};

/// A CA file larger than this is not one (the system's whole bundle is about 200 KiB).
const CA_FILE_MAX: u64 = 4 << 20;

/// The client configuration: the certificates of `ca_file`, else the system's.
pub fn client_config(ca_file: Option<&Path>) -> anyhow::Result<Arc<ClientConfig>> {
    let mut roots = RootCertStore::empty();
    match ca_file {
        Some(path) => {
            let pem = buslab_link::fs::read_limited(path, CA_FILE_MAX)
                .with_context(|| "--ca-file".to_string())?;
            for cert in CertificateDer::pem_slice_iter(&pem) {
                let cert = cert.with_context(|| {
                    format!("--ca-file {}: not a PEM certificate file", path.display())
                })?;
                roots.add(cert).with_context(|| {
                    format!(
                        "--ca-file {}: a certificate rustls cannot use",
                        path.display()
                    )
                })?;
            }
            if roots.is_empty() {
                bail!(
                    "--ca-file {}: no certificate in it (PEM, \"-----BEGIN CERTIFICATE-----\")",
                    path.display()
                );
            }
        }
        None => {
            let found = rustls_native_certs::load_native_certs();
            for error in &found.errors {
                tracing::debug!("system certificates: {error}");
            }
            let (added, _ignored) = roots.add_parsable_certificates(found.certs);
            if added == 0 {
                bail!(
                    "no trusted certificate found on this system ({}); give the server's CA with --ca-file PATH",
                    found
                        .errors
                        .first()
                        .map(|e| e.to_string())
                        .unwrap_or_else(|| "none in the usual places".into())
                );
            }
        }
    }
    let provider = Arc::new(rustls::crypto::ring::default_provider());
    let config = ClientConfig::builder_with_provider(provider)
        .with_safe_default_protocol_versions()
        .context("TLS protocol versions")?
        .with_root_certificates(roots)
        .with_no_client_auth();
    Ok(Arc::new(config))
}

pub type TlsStream = StreamOwned<ClientConnection, TcpStream>;

/// The TLS handshake on `tcp` with `host` (a name or an IP address, checked against the
/// certificate), done by `deadline`.
pub fn handshake(
    config: &Arc<ClientConfig>,
    host: &str,
    mut tcp: TcpStream,
    deadline: Instant,
) -> anyhow::Result<TlsStream> {
    let name = ServerName::try_from(host.to_string())
        .with_context(|| format!("{host:?} is not a host name TLS can check"))?;
    let mut conn = ClientConnection::new(config.clone(), name).context("TLS set-up")?;
    while conn.is_handshaking() {
        let left = deadline.saturating_duration_since(Instant::now());
        if left.is_zero() {
            bail!("the TLS handshake did not complete in time");
        }
        tcp.set_read_timeout(Some(left))?;
        tcp.set_write_timeout(Some(left))?;
        match conn.complete_io(&mut tcp) {
            Ok(_) => {}
            Err(e)
                if matches!(
                    e.kind(),
                    io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut
                ) =>
            {
                bail!("the TLS handshake did not complete in time")
            }
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e).context("the TLS handshake failed"),
        }
    }
    Ok(StreamOwned::new(conn, tcp))
}
