//! The state every handler shares, and the token rule for writes.

use std::sync::Arc;

use axum::http::{HeaderMap, HeaderValue};
use buslab_backends::PumpSender;

use crate::TOKEN_HEADER;
use crate::error::ApiError;
use crate::guard::HostGuard;
use crate::hub::Hub;
use crate::limits::Timeouts;

#[derive(Clone)]
pub struct App {
    pub hub: Arc<Hub>,
    pub sender: PumpSender,
    pub token: Option<Arc<str>>,
    /// The hosts this server answers to.
    pub hosts: Arc<HostGuard>,
    pub timeouts: Timeouts,
    /// A joined bus's counters.
    pub join: Option<buslab_backends::JoinSender>,
}

/// Writes need the server's token in the `X-Buslab-Token` header
/// ([`crate::request::check_token`]).
pub fn authorize(app: &App, headers: &HeaderMap) -> Result<(), ApiError> {
    crate::request::check_token(
        app.token.as_deref(),
        headers.get(TOKEN_HEADER).map(HeaderValue::as_bytes),
    )
}
