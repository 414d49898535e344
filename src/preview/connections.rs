//! Accepting connections, with the bounds `axum::serve` lacks: at most
//! [`MAX_CONNECTIONS`] open at once (a page's websocket counts until it
//! closes); a connection that sends no request headers within
//! [`HEADER_TIMEOUT`] (a new one, or one kept alive between requests) is
//! closed; the handlers bound a request's body by [`BODY_TIMEOUT`]; and a
//! reply the client has not taken for [`WRITE_TIMEOUT`] ends the
//! connection. Without them a client holding idle, half-sent or unread
//! requests held its slot for ever, and every new page then waited. Past
//! the cap, new connections wait in the kernel's backlog, not in ours. TCP
//! keepalive and `TCP_USER_TIMEOUT` free the slot of a peer that vanished
//! (a laptop off the network with `--host`) within about two minutes,
//! whether or not a reply was in flight.

use std::future::Future;
use std::io;
use std::pin::Pin;
use std::sync::Arc;
use std::task::{Context, Poll};
use std::time::Duration;

use axum::Router;
use hyper::server::conn::http1;
use hyper_util::rt::{TokioIo, TokioTimer};
use hyper_util::service::TowerToHyperService;
use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::{OwnedSemaphorePermit, Semaphore};

/// Connections served at once: well under a desktop's 1,024 file
/// descriptors (memory: README Limits).
pub const MAX_CONNECTIONS: usize = 256;

/// How long a connection may wait before its request's headers are in.
pub const HEADER_TIMEOUT: Duration = Duration::from_secs(30);

/// How long a request's body may take to arrive once its headers are in
/// (a frame request is a few hundred bytes, the limit 2 MiB).
pub const BODY_TIMEOUT: Duration = Duration::from_secs(30);

/// How long a reply may wait for the client to take it (a page reads
/// every frame as it comes; a client that does not is gone or hostile).
pub const WRITE_TIMEOUT: Duration = Duration::from_secs(30);

/// TCP keepalive: first probe after a minute idle, then every 10 s; and
/// sent data unacknowledged for two minutes ends the connection (Linux
/// probes only idle connections).
const KEEPALIVE_IDLE: Duration = Duration::from_secs(60);
const KEEPALIVE_INTERVAL: Duration = Duration::from_secs(10);
const KEEPALIVE_PROBES: u32 = 6;
const UNACKNOWLEDGED: Duration = Duration::from_secs(120);

/// Serves `router` on `listener` until the process ends.
pub async fn serve(listener: TcpListener, router: Router) {
    let slots = Arc::new(Semaphore::new(MAX_CONNECTIONS));
    loop {
        // The semaphore is never closed, so acquiring only waits.
        let Ok(slot) = slots.clone().acquire_owned().await else {
            return;
        };
        let stream = match listener.accept().await {
            Ok((stream, _)) => stream,
            Err(e) => {
                // A connection that failed before it was accepted costs
                // nothing; anything else (out of descriptors) is waited out.
                if !is_connection_error(&e) {
                    tokio::time::sleep(Duration::from_millis(200)).await;
                }
                continue;
            }
        };
        keep_alive(&stream);
        let io = TokioIo::new(Counted {
            stream,
            _slot: slot,
            stalled: None,
        });
        let service = TowerToHyperService::new(router.clone());
        tokio::spawn(async move {
            let mut builder = http1::Builder::new();
            builder.timer(TokioTimer::new()).header_read_timeout(HEADER_TIMEOUT);
            // An error here is the client's (it went, or sent garbage); the
            // connection is simply closed.
            let _ = builder.serve_connection(io, service).with_upgrades().await;
        });
    }
}

/// Turns TCP keepalive and the unacknowledged-data timeout on for
/// `stream` (best effort: a failure leaves the connection as the system
/// made it).
fn keep_alive(stream: &TcpStream) {
    let socket = socket2::SockRef::from(stream);
    let keepalive = socket2::TcpKeepalive::new()
        .with_time(KEEPALIVE_IDLE)
        .with_interval(KEEPALIVE_INTERVAL)
        .with_retries(KEEPALIVE_PROBES);
    let _ = socket.set_tcp_keepalive(&keepalive);
    let _ = socket.set_tcp_user_timeout(Some(UNACKNOWLEDGED));
}

fn is_connection_error(e: &io::Error) -> bool {
    matches!(
        e.kind(),
        io::ErrorKind::ConnectionRefused | io::ErrorKind::ConnectionAborted | io::ErrorKind::ConnectionReset
    )
}

/// A connection holding its slot: the slot is freed when the stream is
/// dropped, which for a websocket is when the socket closes (the upgrade
/// carries the stream, and this with it). A write the client leaves
/// waiting for [`WRITE_TIMEOUT`] fails, which ends the connection.
struct Counted {
    stream: TcpStream,
    _slot: OwnedSemaphorePermit,
    /// Since when writes have waited for the client, as a deadline.
    stalled: Option<Pin<Box<tokio::time::Sleep>>>,
}

impl Counted {
    /// `poll` (a write or flush) bounded by [`WRITE_TIMEOUT`] of waiting.
    fn bounded<T>(
        &mut self,
        cx: &mut Context<'_>,
        poll: impl FnOnce(Pin<&mut TcpStream>, &mut Context<'_>) -> Poll<io::Result<T>>,
    ) -> Poll<io::Result<T>> {
        match poll(Pin::new(&mut self.stream), cx) {
            Poll::Pending => {
                let stalled = self
                    .stalled
                    .get_or_insert_with(|| Box::pin(tokio::time::sleep(WRITE_TIMEOUT)));
                match stalled.as_mut().poll(cx) {
                    Poll::Ready(()) => Poll::Ready(Err(io::Error::new(
                        io::ErrorKind::TimedOut,
                        format!("the client took nothing of the reply for {} s", WRITE_TIMEOUT.as_secs()),
                    ))),
                    Poll::Pending => Poll::Pending,
                }
            }
            done => {
                self.stalled = None;
                done
            }
        }
    }
}

impl AsyncRead for Counted {
    fn poll_read(mut self: Pin<&mut Self>, cx: &mut Context<'_>, buf: &mut ReadBuf<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.stream).poll_read(cx, buf)
    }
}

impl AsyncWrite for Counted {
    fn poll_write(mut self: Pin<&mut Self>, cx: &mut Context<'_>, buf: &[u8]) -> Poll<io::Result<usize>> {
        self.bounded(cx, |s, cx| s.poll_write(cx, buf))
    }

    fn poll_write_vectored(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        bufs: &[io::IoSlice<'_>],
    ) -> Poll<io::Result<usize>> {
        self.bounded(cx, |s, cx| s.poll_write_vectored(cx, bufs))
    }

    fn is_write_vectored(&self) -> bool {
        self.stream.is_write_vectored()
    }

    fn poll_flush(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        self.bounded(cx, |s, cx| s.poll_flush(cx))
    }

    fn poll_shutdown(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.stream).poll_shutdown(cx)
    }
}
