//! Accepting connections, with the bounds `axum::serve` lacks: at most
//! [`MAX_CONNECTIONS`] open at once (a page's websocket counts until it
//! closes), and a connection that sends no request headers within
//! [`HEADER_TIMEOUT`] (a new one, or one kept alive between requests) is
//! closed; the handlers bound a request's body by [`BODY_TIMEOUT`]. Without
//! them a client holding idle or half-sent requests used up the process's
//! file descriptors, and every new page then waited. Past the cap, new
//! connections wait in the kernel's backlog, not in ours. TCP keepalive
//! frees the slot of a peer that vanished (a laptop off the network with
//! `--host`) within about two minutes.

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

/// TCP keepalive: first probe after a minute idle, then every 10 s; six
/// unanswered probes end the connection.
const KEEPALIVE_IDLE_S: libc::c_int = 60;
const KEEPALIVE_INTERVAL_S: libc::c_int = 10;
const KEEPALIVE_PROBES: libc::c_int = 6;

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
        let io = TokioIo::new(Counted { stream, _slot: slot });
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

/// Turns TCP keepalive on for `stream` (best effort: a failure leaves the
/// connection as the system made it).
fn keep_alive(stream: &TcpStream) {
    use std::os::fd::AsRawFd;
    let fd = stream.as_raw_fd();
    let set = |level, name, value: libc::c_int| {
        // SAFETY: setsockopt on a socket this process owns, with a pointer
        // to an int and its size.
        unsafe {
            libc::setsockopt(
                fd,
                level,
                name,
                std::ptr::from_ref(&value).cast(),
                std::mem::size_of::<libc::c_int>() as libc::socklen_t,
            )
        }
    };
    set(libc::SOL_SOCKET, libc::SO_KEEPALIVE, 1);
    set(libc::IPPROTO_TCP, libc::TCP_KEEPIDLE, KEEPALIVE_IDLE_S);
    set(libc::IPPROTO_TCP, libc::TCP_KEEPINTVL, KEEPALIVE_INTERVAL_S);
    set(libc::IPPROTO_TCP, libc::TCP_KEEPCNT, KEEPALIVE_PROBES);
}

fn is_connection_error(e: &io::Error) -> bool {
    matches!(
        e.kind(),
        io::ErrorKind::ConnectionRefused | io::ErrorKind::ConnectionAborted | io::ErrorKind::ConnectionReset
    )
}

/// A connection holding its slot: the slot is freed when the stream is
/// dropped, which for a websocket is when the socket closes (the upgrade
/// carries the stream, and this with it).
struct Counted {
    stream: TcpStream,
    _slot: OwnedSemaphorePermit,
}

impl AsyncRead for Counted {
    fn poll_read(mut self: Pin<&mut Self>, cx: &mut Context<'_>, buf: &mut ReadBuf<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.stream).poll_read(cx, buf)
    }
}

impl AsyncWrite for Counted {
    fn poll_write(mut self: Pin<&mut Self>, cx: &mut Context<'_>, buf: &[u8]) -> Poll<io::Result<usize>> {
        Pin::new(&mut self.stream).poll_write(cx, buf)
    }

    fn poll_write_vectored(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        bufs: &[io::IoSlice<'_>],
    ) -> Poll<io::Result<usize>> {
        Pin::new(&mut self.stream).poll_write_vectored(cx, bufs)
    }

    fn is_write_vectored(&self) -> bool {
        self.stream.is_write_vectored()
    }

    fn poll_flush(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.stream).poll_flush(cx)
    }

    fn poll_shutdown(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.stream).poll_shutdown(cx)
    }
}
