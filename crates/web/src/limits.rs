//! How long a client may hold a connection without doing its part, so that a few connections
//! that stall cannot keep the others out (each holds one of `--max-connections`):
//!
//! - a request head must arrive within the request timeout, and so must the next one on a
//!   kept-alive connection (hyper's header timer, restarted when a connection goes idle);
//! - a request's body too, from the moment its head arrived ([`read_body`]): a POST that
//!   announces a body and never sends it is answered 408 and closed;
//! - an answer that the client stops reading is cut once no byte could be written for the
//!   stall limit ([`StallGuard`]). A live dashboard reads all the time, so its stream of
//!   updates (long-lived by design) never stalls; a viewer that stops reading holds its
//!   socket's buffers and one update until then, and its connection after that.

use std::future::Future;
use std::io;
use std::pin::Pin;
use std::task::{Context, Poll};
use std::time::Duration;

use axum::body::{Body, Bytes};
use axum::http::StatusCode;
use futures_util::StreamExt;
use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::time::Sleep;

use crate::error::ApiError;

/// How long a client may take, as configured ([`crate::WebConfig`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Timeouts {
    /// A request head, and its body after it; also how long a kept-alive connection may sit
    /// idle between requests.
    pub request: Duration,
    /// How long an answer may make no progress because the client does not read.
    pub stalled_write: Duration,
}

impl Default for Timeouts {
    fn default() -> Self {
        Self {
            request: Duration::from_secs(10),
            stalled_write: Duration::from_secs(60),
        }
    }
}

/// Reads a request's whole body: at most `limit` bytes (413 beyond), within `within` of the
/// head (408 after, and the connection is closed: the rest of the body may never come).
pub async fn read_body(body: Body, limit: usize, within: Duration) -> Result<Bytes, ApiError> {
    let read = async {
        let mut data = Vec::new();
        let mut chunks = body.into_data_stream();
        while let Some(chunk) = chunks.next().await {
            let chunk = chunk
                .map_err(|e| ApiError::bad_request(format!("the request body is broken: {e}")))?;
            if data.len() + chunk.len() > limit {
                return Err(ApiError::new(
                    StatusCode::PAYLOAD_TOO_LARGE,
                    format!("the request body is over {limit} bytes, the most accepted"),
                ));
            }
            data.extend_from_slice(&chunk);
        }
        Ok(Bytes::from(data))
    };
    match tokio::time::timeout(within, read).await {
        Ok(read) => read,
        Err(_) => Err(ApiError::new(
            StatusCode::REQUEST_TIMEOUT,
            format!(
                "the request body did not arrive within {} ms of its head",
                within.as_millis()
            ),
        )),
    }
}

/// A connection whose writes fail with `TimedOut` once none could make progress for the
/// stall limit (the client does not read); reads pass through.
pub struct StallGuard<T> {
    io: T,
    limit: Duration,
    /// Running while the last write or flush was pending.
    stalled: Option<Pin<Box<Sleep>>>,
}

impl<T> StallGuard<T> {
    pub fn new(io: T, limit: Duration) -> Self {
        Self {
            io,
            limit,
            stalled: None,
        }
    }

    /// After a write or flush said `poll`: clears the timer on progress, and on no progress
    /// starts it (or fails once it ran out).
    fn watch<R>(&mut self, poll: Poll<io::Result<R>>, cx: &mut Context<'_>) -> Poll<io::Result<R>> {
        if poll.is_ready() {
            self.stalled = None;
            return poll;
        }
        let limit = self.limit;
        let timer = self
            .stalled
            .get_or_insert_with(|| Box::pin(tokio::time::sleep(limit)));
        match timer.as_mut().poll(cx) {
            Poll::Ready(()) => Poll::Ready(Err(io::Error::new(
                io::ErrorKind::TimedOut,
                format!(
                    "the client read nothing for {} ms: connection closed",
                    limit.as_millis()
                ),
            ))),
            Poll::Pending => Poll::Pending,
        }
    }
}

impl<T: AsyncRead + Unpin> AsyncRead for StallGuard<T> {
    fn poll_read(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<io::Result<()>> {
        Pin::new(&mut self.get_mut().io).poll_read(cx, buf)
    }
}

impl<T: AsyncWrite + Unpin> AsyncWrite for StallGuard<T> {
    fn poll_write(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &[u8],
    ) -> Poll<io::Result<usize>> {
        let this = self.get_mut();
        let poll = Pin::new(&mut this.io).poll_write(cx, buf);
        this.watch(poll, cx)
    }

    fn poll_write_vectored(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        bufs: &[io::IoSlice<'_>],
    ) -> Poll<io::Result<usize>> {
        let this = self.get_mut();
        let poll = Pin::new(&mut this.io).poll_write_vectored(cx, bufs);
        this.watch(poll, cx)
    }

    fn is_write_vectored(&self) -> bool {
        self.io.is_write_vectored()
    }

    fn poll_flush(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        let this = self.get_mut();
        let poll = Pin::new(&mut this.io).poll_flush(cx);
        this.watch(poll, cx)
    }

    fn poll_shutdown(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        let this = self.get_mut();
        let poll = Pin::new(&mut this.io).poll_shutdown(cx);
        this.watch(poll, cx)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use tokio::io::AsyncWriteExt;

    #[tokio::test(start_paused = true)]
    async fn a_write_nobody_reads_fails_after_the_stall_limit_and_not_before() {
        let (near, mut far) = tokio::io::duplex(64);
        let limit = Duration::from_secs(5);
        let mut guarded = StallGuard::new(near, limit);
        let started = tokio::time::Instant::now();
        guarded.write_all(&[0; 64]).await.unwrap();
        // The pipe is full: the next write waits, then fails.
        let e = guarded.write_all(&[0; 1]).await.unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::TimedOut);
        assert_eq!(started.elapsed(), limit);
        // A reader that keeps up never lets it stall.
        let (near, mut far2) = tokio::io::duplex(64);
        let mut guarded = StallGuard::new(near, limit);
        let reader = tokio::spawn(async move {
            let mut sink = Vec::new();
            tokio::io::AsyncReadExt::read_to_end(&mut far2, &mut sink)
                .await
                .map(|_| sink.len())
        });
        for _ in 0..100 {
            guarded.write_all(&[1; 64]).await.unwrap();
            tokio::time::sleep(limit / 2).await;
        }
        drop(guarded);
        assert_eq!(reader.await.unwrap().unwrap(), 6400);
        drop(far.shutdown().await);
    }

    #[tokio::test(start_paused = true)]
    async fn a_body_is_read_whole_or_refused_with_its_reason() {
        let ok = read_body(Body::from("{}"), 10, Duration::from_secs(1)).await;
        assert_eq!(ok.unwrap(), Bytes::from_static(b"{}"));
        let big = read_body(Body::from(vec![0u8; 11]), 10, Duration::from_secs(1))
            .await
            .unwrap_err();
        assert_eq!(big.status, StatusCode::PAYLOAD_TOO_LARGE);
        // A body that never ends.
        let never = Body::from_stream(futures_util::stream::pending::<Result<Bytes, io::Error>>());
        let late = read_body(never, 10, Duration::from_secs(3))
            .await
            .unwrap_err();
        assert_eq!(late.status, StatusCode::REQUEST_TIMEOUT);
        assert!(late.reason.contains("3000 ms"), "{}", late.reason);
    }
}
