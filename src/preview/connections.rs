//! Accepting connections, with the bounds `axum::serve` lacks: at most
//! [`MAX_CONNECTIONS`] open at once (a page's websocket counts until it
//! closes); a connection that sends no request headers within
//! [`HEADER_TIMEOUT`] (a new one, or one kept alive between requests) is
//! closed; the handlers bound a request's body by [`BODY_TIMEOUT`]; and a
//! reply of which the client has taken less than [`MIN_TAKEN`] in
//! [`WRITE_TIMEOUT`] ends the connection. Without them a client holding
//! idle, half-sent or unread requests held its slot for ever, and every
//! new page then waited. Past
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

/// What a client must take of a waiting reply within [`WRITE_TIMEOUT`] to
/// keep its connection (about 2 KB/s): a client taking a few bytes now
/// and then does not hold a reply, and its slot, for hours.
pub const MIN_TAKEN: usize = 64 * 1024;

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
/// carries the stream, and this with it). A write that waits
/// [`WRITE_TIMEOUT`] while the client takes less than [`MIN_TAKEN`]
/// fails, which ends the connection.
struct Counted {
    stream: TcpStream,
    _slot: OwnedSemaphorePermit,
    /// Since when writes have waited for the client.
    stalled: Option<Stall>,
}

/// A write waiting for room in the socket's send buffer.
struct Stall {
    /// When the wait is taken for the client's absence.
    deadline: Pin<Box<tokio::time::Sleep>>,
    /// Bytes in the socket's send queue when the deadline was set.
    queued: Option<usize>,
}

impl Stall {
    fn new(stream: &TcpStream) -> Self {
        Stall {
            deadline: Box::pin(tokio::time::sleep(WRITE_TIMEOUT)),
            queued: send_queue(stream),
        }
    }
}

/// Bytes sent on `stream` and not yet acknowledged, or not yet sent
/// (`SIOCOUTQ`); None where the system does not say.
fn send_queue(stream: &TcpStream) -> Option<usize> {
    use std::os::fd::AsRawFd;
    let mut queued: libc::c_int = 0;
    // SAFETY: SIOCOUTQ (TIOCOUTQ) writes one int through the pointer, on a
    // descriptor `stream` owns for the call.
    #[allow(unsafe_code)]
    let rc = unsafe { libc::ioctl(stream.as_raw_fd(), libc::TIOCOUTQ, &mut queued) };
    (rc == 0).then(|| usize::try_from(queued).ok()).flatten()
}

impl Counted {
    /// `poll` (a write or flush) bounded by [`WRITE_TIMEOUT`] of waiting
    /// while the client takes less than [`MIN_TAKEN`]. A full send buffer
    /// wakes its writer only once about a third of it is free, which a
    /// client that reads slowly but steadily (under about 45 KB/s of a
    /// 4 MB buffer) takes longer than the timeout to make: so when the
    /// deadline comes and the send queue has shrunk by `MIN_TAKEN` since it
    /// was set, the client is still there, and a new deadline is set.
    fn bounded<T>(
        &mut self,
        cx: &mut Context<'_>,
        poll: impl FnOnce(Pin<&mut TcpStream>, &mut Context<'_>) -> Poll<io::Result<T>>,
    ) -> Poll<io::Result<T>> {
        match poll(Pin::new(&mut self.stream), cx) {
            Poll::Pending => loop {
                let stall = self.stalled.get_or_insert_with(|| Stall::new(&self.stream));
                if stall.deadline.as_mut().poll(cx).is_pending() {
                    return Poll::Pending;
                }
                let now = send_queue(&self.stream);
                if matches!((stall.queued, now), (Some(before), Some(now)) if now + MIN_TAKEN <= before) {
                    // Polled again at the loop's top, so the new deadline
                    // wakes this task.
                    self.stalled = None;
                    continue;
                }
                return Poll::Ready(Err(io::Error::new(
                    io::ErrorKind::TimedOut,
                    format!(
                        "the client took less than {} KiB of the reply in {} s",
                        MIN_TAKEN / 1024,
                        WRITE_TIMEOUT.as_secs()
                    ),
                )));
            },
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

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Read;
    use std::task::Waker;

    /// A served stream whose send buffer (about 1 MB) is full, and its client,
    /// whose small receive buffer leaves what the server wrote queued on
    /// the server's side. Filled before tokio takes the stream: tokio
    /// writes only once its reactor has seen the socket writable.
    fn pair() -> (Counted, std::net::TcpStream) {
        let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        let client = socket2::Socket::new(socket2::Domain::IPV4, socket2::Type::STREAM, None).unwrap();
        client.set_recv_buffer_size(4096).unwrap();
        client.connect(&listener.local_addr().unwrap().into()).unwrap();
        let (server, _) = listener.accept().unwrap();
        socket2::SockRef::from(&server)
            .set_send_buffer_size(512 * 1024)
            .unwrap();
        server.set_nonblocking(true).unwrap();
        let mut filled = 0;
        loop {
            match std::io::Write::write(&mut &server, &[7u8; 16384]) {
                Ok(n) => filled += n,
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => break,
                Err(e) => panic!("{e}"),
            }
        }
        assert!(filled > 16384);
        let slot = Arc::new(Semaphore::new(1)).try_acquire_owned().unwrap();
        let counted = Counted {
            stream: TcpStream::from_std(server).unwrap(),
            _slot: slot,
            stalled: None,
        };
        (counted, client.into())
    }

    fn write_once(c: &mut Counted) -> Poll<io::Result<usize>> {
        Pin::new(c).poll_write(&mut Context::from_waker(Waker::noop()), &[7u8; 16384])
    }

    /// A write into the full buffer: it waits, and its deadline (if none
    /// runs yet) runs from now.
    fn wait(c: &mut Counted) {
        assert!(write_once(c).is_pending());
    }

    /// Reads `n` bytes as the client (less than a third of the server's
    /// buffer, so the server's writer is not woken), then waits until the
    /// server's send queue has shrunk by `shrink` (what the client's
    /// window let through was acknowledged).
    fn take(client: &mut std::net::TcpStream, c: &Counted, n: usize, shrink: usize) {
        let before = send_queue(&c.stream).unwrap();
        let mut buf = vec![0u8; n];
        client.read_exact(&mut buf).unwrap();
        for _ in 0..200 {
            if send_queue(&c.stream).unwrap() + shrink <= before {
                return;
            }
            std::thread::sleep(std::time::Duration::from_millis(5));
        }
        panic!("the send queue did not shrink by {shrink}");
    }

    #[tokio::test(start_paused = true)]
    async fn a_client_taking_nothing_for_the_timeout_is_cut() {
        let (mut c, _client) = pair();
        wait(&mut c);
        tokio::time::advance(WRITE_TIMEOUT - Duration::from_secs(1)).await;
        assert!(write_once(&mut c).is_pending());
        tokio::time::advance(Duration::from_secs(2)).await;
        match write_once(&mut c) {
            Poll::Ready(Err(e)) => assert_eq!(
                (e.kind(), e.to_string()),
                (
                    io::ErrorKind::TimedOut,
                    "the client took less than 64 KiB of the reply in 30 s".into()
                )
            ),
            other => panic!("{other:?}"),
        }
    }

    #[tokio::test(start_paused = true)]
    async fn a_client_taking_enough_before_the_timeout_gets_another() {
        // Before, a write waiting 30 s failed even when the client had
        // taken part of the queue meanwhile: the kernel wakes a writer only
        // once about a third of its buffer is free.
        let (mut c, mut client) = pair();
        wait(&mut c);
        take(&mut client, &c, MIN_TAKEN + 16384, MIN_TAKEN);
        tokio::time::advance(WRITE_TIMEOUT + Duration::from_secs(1)).await;
        assert!(matches!(write_once(&mut c), Poll::Pending | Poll::Ready(Ok(_))));
        // Then too little taken in a whole new timeout: cut.
        wait(&mut c);
        take(&mut client, &c, 4096, 1);
        tokio::time::advance(WRITE_TIMEOUT + Duration::from_secs(1)).await;
        assert!(matches!(write_once(&mut c), Poll::Ready(Err(e)) if e.kind() == io::ErrorKind::TimedOut));
    }

    #[test]
    fn the_send_queue_counts_unacknowledged_bytes() {
        let rt = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .unwrap();
        rt.block_on(async {
            let (c, _client) = pair();
            assert!(send_queue(&c.stream).unwrap() > 16384);
        });
    }
}
