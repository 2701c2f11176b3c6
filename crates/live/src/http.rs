//! The live view's own HTTP/1.1 server: one connection, one request, one answer
//! (`Connection: close`), on a thread of its own with a small stack — at most
//! [`MAX_CONNECTIONS`] at once. A connection beyond them is answered 503 by the accepting
//! thread and closed, without a thread; one that sends no whole request head within
//! [`HEAD_TIMEOUT`] is closed. So the threads and stack memory a client can make the service
//! hold are bounded, whatever it does (the LinuxCNC component locks every thread's stack).
//!
//! Written here rather than taken from a library: tiny_http, used before, gives every
//! connection a thread of its own with the default 2 MiB stack and no bound, and the answers here
//! (GET of seven paths, a stream) need no more than this.

use std::io::{self, BufRead, BufReader, Read, Write};
use std::net::{Shutdown, SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// Connections served at once (streams included); more are answered 503.
pub const MAX_CONNECTIONS: usize = 24;
/// Time a client has to send its request's head.
pub const HEAD_TIMEOUT: Duration = Duration::from_secs(5);
/// Largest request head (request line and headers).
const MAX_HEAD: usize = 16 * 1024;
/// Largest request body read (and discarded) so that the answer reaches the client.
const MAX_BODY: u64 = 64 * 1024;
/// Time an answer may take to write before the client is given up.
const WRITE_TIMEOUT: Duration = Duration::from_secs(10);

/// One request as read: method, target and headers; the connection to answer on.
#[derive(Debug)]
pub struct Request {
    method: String,
    url: String,
    headers: Vec<(String, String)>,
    stream: TcpStream,
}

impl Request {
    /// `GET`, `HEAD`, `POST`, …
    pub fn method(&self) -> &str {
        &self.method
    }

    /// The target as sent (`/api/history?window_s=900`).
    pub fn url(&self) -> &str {
        &self.url
    }

    /// A header's value (the name case-insensitive).
    pub fn header(&self, name: &str) -> Option<&str> {
        self.headers
            .iter()
            .find(|(n, _)| n.eq_ignore_ascii_case(name))
            .map(|(_, v)| v.as_str())
    }

    /// Answers with `status`, the headers and the body (not sent for `HEAD`), and closes.
    pub fn respond(mut self, status: u16, headers: &[(&str, &str)], body: &[u8]) {
        let mut head = format!(
            "HTTP/1.1 {status} {}\r\nContent-Length: {}\r\nConnection: close\r\n",
            reason(status),
            body.len()
        );
        for (n, v) in headers {
            head += &format!("{n}: {v}\r\n");
        }
        head += "\r\n";
        let _ = self.stream.set_write_timeout(Some(WRITE_TIMEOUT));
        let mut out = head.into_bytes();
        if self.method != "HEAD" {
            out.extend_from_slice(body);
        }
        let _ = self
            .stream
            .write_all(&out)
            .and_then(|()| self.stream.flush());
        let _ = self.stream.shutdown(Shutdown::Write);
    }

    /// The connection, for an answer written as it goes (a stream): its writes time out.
    pub fn into_stream(self) -> TcpStream {
        let _ = self.stream.set_write_timeout(Some(WRITE_TIMEOUT));
        self.stream
    }
}

fn reason(status: u16) -> &'static str {
    match status {
        200 => "OK",
        400 => "Bad Request",
        401 => "Unauthorized",
        404 => "Not Found",
        405 => "Method Not Allowed",
        431 => "Request Header Fields Too Large",
        500 => "Internal Server Error",
        503 => "Service Unavailable",
        _ => "",
    }
}

/// What reading a request's head gave.
enum Head {
    Request(Request),
    /// Malformed or too large: answered with this status.
    Refused(TcpStream, u16),
    /// Closed or timed out before a whole head: nothing to answer.
    Gone,
}

/// A socket read with one deadline for the whole request, however its bytes trickle in: each
/// read may wait only for what is left of it (a socket's read timeout alone restarts with every
/// byte, so a client sending one byte every few seconds would hold a thread for hours).
struct UntilDeadline {
    stream: TcpStream,
    deadline: Instant,
}

impl Read for UntilDeadline {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let left = self.deadline.saturating_duration_since(Instant::now());
        if left.is_zero() {
            return Err(io::Error::new(io::ErrorKind::TimedOut, "request deadline"));
        }
        self.stream.set_read_timeout(Some(left))?;
        self.stream.read(buf)
    }
}

fn read_request(stream: TcpStream) -> Head {
    let Ok(reader) = stream.try_clone() else {
        return Head::Gone;
    };
    let reader = UntilDeadline {
        stream: reader,
        deadline: Instant::now() + HEAD_TIMEOUT,
    };
    let mut reader = BufReader::with_capacity(4096, reader);
    let mut lines: Vec<String> = Vec::new();
    let mut size = 0;
    loop {
        let mut line = Vec::new();
        // At most the rest of the head's budget, plus one to tell a head too large.
        let budget = (MAX_HEAD - size) as u64 + 1;
        match (&mut reader).take(budget).read_until(b'\n', &mut line) {
            Ok(0) | Err(_) => return Head::Gone,
            Ok(n) => size += n,
        }
        if size > MAX_HEAD {
            return Head::Refused(stream, 431);
        }
        if !line.ends_with(b"\n") {
            return Head::Gone; // closed within a line
        }
        let text = String::from_utf8_lossy(&line).trim_end().to_string();
        if text.is_empty() {
            if lines.is_empty() {
                continue; // a stray line break before the request line
            }
            break;
        }
        lines.push(text);
    }
    let mut first = lines[0].split(' ');
    let (Some(method), Some(url), Some(version)) = (first.next(), first.next(), first.next())
    else {
        return Head::Refused(stream, 400);
    };
    if !version.starts_with("HTTP/1.") || !url.starts_with('/') {
        return Head::Refused(stream, 400);
    }
    let mut headers = Vec::with_capacity(lines.len() - 1);
    for l in &lines[1..] {
        let Some((n, v)) = l.split_once(':') else {
            return Head::Refused(stream, 400);
        };
        headers.push((n.trim().to_string(), v.trim().to_string()));
    }
    let rq = Request {
        method: method.to_string(),
        url: url.to_string(),
        headers,
        stream,
    };
    // A small body is read and dropped: closing on unread data would reset the connection
    // before the client read the answer.
    if let Some(n) = rq
        .header("Content-Length")
        .and_then(|v| v.parse::<u64>().ok())
    {
        let _ = io::copy(&mut (&mut reader).take(n.min(MAX_BODY)), &mut io::sink());
    }
    Head::Request(rq)
}

/// Answers a connection beyond the bound, on the accepting thread: a short write into the
/// socket's buffer, then closed.
fn refuse_busy(mut stream: TcpStream) {
    let _ = stream.set_write_timeout(Some(Duration::from_millis(200)));
    let body = "too many connections to the live view; try again shortly\n";
    let _ = write!(
        stream,
        "HTTP/1.1 503 Service Unavailable\r\nContent-Type: text/plain; charset=utf-8\r\n\
         Content-Length: {}\r\nRetry-After: 5\r\nConnection: close\r\n\r\n{body}",
        body.len()
    );
    let _ = stream.shutdown(Shutdown::Both);
}

/// The listening server: the accepting thread and the count of connections open.
pub struct Server {
    addr: SocketAddr,
    stop: Arc<AtomicBool>,
    open: Arc<AtomicUsize>,
    acceptor: Option<JoinHandle<()>>,
}

/// What answers one request (on its connection's thread).
pub type Handler = dyn Fn(Request) + Send + Sync;

impl Server {
    /// Binds `addr` and starts accepting; each request goes to `handler` on a thread of
    /// `stack_bytes`.
    pub fn start(addr: SocketAddr, stack_bytes: usize, handler: Arc<Handler>) -> io::Result<Self> {
        let listener = TcpListener::bind(addr)?;
        let addr = listener.local_addr()?;
        let stop = Arc::new(AtomicBool::new(false));
        let open = Arc::new(AtomicUsize::new(0));
        let acceptor = {
            let (stop, open) = (Arc::clone(&stop), Arc::clone(&open));
            std::thread::Builder::new()
                .name("truepos-live-accept".into())
                .stack_size(stack_bytes)
                .spawn(move || accept(&listener, &stop, &open, stack_bytes, &handler))?
        };
        Ok(Self {
            addr,
            stop,
            open,
            acceptor: Some(acceptor),
        })
    }

    /// The address it listens on.
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// Connections open now.
    pub fn connections(&self) -> usize {
        self.open.load(Ordering::Relaxed)
    }

    /// Stops accepting (the connections open end on their own: streams within a second once
    /// the hub stops), waiting at most `wait` for them.
    pub fn stop(&mut self, wait: Duration) {
        self.stop.store(true, Ordering::Relaxed);
        // The accepting thread waits in accept(): a connection of our own wakes it.
        let mut wake = self.addr;
        if wake.ip().is_unspecified() {
            wake.set_ip(match wake {
                SocketAddr::V4(_) => [127, 0, 0, 1].into(),
                SocketAddr::V6(_) => std::net::Ipv6Addr::LOCALHOST.into(),
            });
        }
        let _ = TcpStream::connect_timeout(&wake, Duration::from_secs(1));
        if let Some(t) = self.acceptor.take() {
            let _ = t.join();
        }
        let until = Instant::now() + wait;
        while self.open.load(Ordering::Relaxed) > 0 && Instant::now() < until {
            std::thread::sleep(Duration::from_millis(20));
        }
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        if self.acceptor.is_some() {
            self.stop(Duration::from_secs(2));
        }
    }
}

/// Counts a connection open until dropped.
struct Open(Arc<AtomicUsize>);

impl Drop for Open {
    fn drop(&mut self) {
        self.0.fetch_sub(1, Ordering::AcqRel);
    }
}

fn accept(
    listener: &TcpListener,
    stop: &AtomicBool,
    open: &Arc<AtomicUsize>,
    stack_bytes: usize,
    handler: &Arc<Handler>,
) {
    for conn in listener.incoming() {
        if stop.load(Ordering::Relaxed) {
            return;
        }
        let Ok(stream) = conn else {
            // Out of descriptors or the like: wait rather than spin.
            std::thread::sleep(Duration::from_millis(50));
            continue;
        };
        if open.fetch_add(1, Ordering::AcqRel) >= MAX_CONNECTIONS {
            open.fetch_sub(1, Ordering::AcqRel);
            refuse_busy(stream);
            continue;
        }
        let guard = Open(Arc::clone(open));
        let handler = Arc::clone(handler);
        let spawned = std::thread::Builder::new()
            .name("truepos-live-conn".into())
            .stack_size(stack_bytes)
            .spawn(move || {
                let _guard = guard;
                match read_request(stream) {
                    Head::Request(rq) => handler(rq),
                    Head::Refused(s, status) => Request {
                        method: "GET".into(),
                        url: "/".into(),
                        headers: Vec::new(),
                        stream: s,
                    }
                    .respond(
                        status,
                        &[("Content-Type", "text/plain; charset=utf-8")],
                        b"bad request\n",
                    ),
                    Head::Gone => {}
                }
            });
        // Not started (out of threads): the guard went with the closure and counted it back.
        drop(spawned);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn served() -> Server {
        let handler: Arc<Handler> = Arc::new(|rq: Request| {
            let body = format!("{} {} {:?}", rq.method(), rq.url(), rq.header("x-test"));
            rq.respond(200, &[("Content-Type", "text/plain")], body.as_bytes());
        });
        Server::start(([127, 0, 0, 1], 0).into(), 256 * 1024, handler).unwrap()
    }

    fn exchange(addr: SocketAddr, request: &str) -> String {
        let mut s = TcpStream::connect(addr).unwrap();
        s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
        s.write_all(request.as_bytes()).unwrap();
        let mut out = String::new();
        let _ = s.read_to_string(&mut out);
        out
    }

    #[test]
    fn a_request_is_answered_and_closed() {
        let mut srv = served();
        let a = srv.addr();
        let r = exchange(a, "GET /x?y=1 HTTP/1.1\r\nHost: h\r\nX-Test: yes\r\n\r\n");
        assert!(r.starts_with("HTTP/1.1 200 OK\r\n"), "{r}");
        assert!(
            r.contains("Content-Length: 22\r\n") && r.contains("Connection: close"),
            "{r}"
        );
        assert!(r.ends_with("GET /x?y=1 Some(\"yes\")"), "{r}");
        let h = exchange(a, "HEAD / HTTP/1.1\r\n\r\n");
        assert!(h.ends_with("\r\n\r\n"), "no body for HEAD: {h}");
        let p = exchange(a, "POST / HTTP/1.1\r\nContent-Length: 5\r\n\r\nhello");
        assert!(p.starts_with("HTTP/1.1 200"), "{p}");
        assert!(exchange(a, "nonsense\r\n\r\n").starts_with("HTTP/1.1 400"));
        let huge = format!("GET / HTTP/1.1\r\nX: {}\r\n\r\n", "a".repeat(MAX_HEAD));
        assert!(exchange(a, &huge).starts_with("HTTP/1.1 431"));
        srv.stop(Duration::from_secs(2));
        assert_eq!(srv.connections(), 0);
    }

    #[test]
    fn connections_beyond_the_bound_are_refused_without_a_thread() {
        let mut srv = served();
        let a = srv.addr();
        // Idle connections hold their threads until the head's time is up.
        let idle: Vec<TcpStream> = (0..MAX_CONNECTIONS)
            .map(|_| TcpStream::connect(a).unwrap())
            .collect();
        let deadline = Instant::now() + Duration::from_secs(3);
        while srv.connections() < MAX_CONNECTIONS {
            assert!(Instant::now() < deadline, "{} open", srv.connections());
            std::thread::sleep(Duration::from_millis(10));
        }
        let r = exchange(a, "GET / HTTP/1.1\r\n\r\n");
        assert!(r.starts_with("HTTP/1.1 503"), "{r}");
        assert!(r.contains("Retry-After: 5"), "{r}");
        drop(idle);
        // Closed by their clients: the threads end and the next request is served.
        let deadline = Instant::now() + Duration::from_secs(3);
        while srv.connections() > 0 {
            assert!(Instant::now() < deadline, "{} open", srv.connections());
            std::thread::sleep(Duration::from_millis(10));
        }
        assert!(exchange(a, "GET / HTTP/1.1\r\n\r\n").starts_with("HTTP/1.1 200"));
        srv.stop(Duration::from_secs(2));
    }

    /// A client that sends its head a byte at a time, each well within a socket timeout, still
    /// loses its connection when the head's whole time is up.
    #[test]
    fn a_trickling_client_is_closed_when_the_heads_time_is_up() {
        let mut srv = served();
        let mut s = TcpStream::connect(srv.addr()).unwrap();
        let start = Instant::now();
        let mut closed = false;
        for b in b"GET / HTTP/1.1\r\nX: ".iter().chain([b'a'; 200].iter()) {
            if s.write_all(&[*b]).is_err() {
                closed = true;
                break;
            }
            std::thread::sleep(Duration::from_millis(100));
            if start.elapsed() > HEAD_TIMEOUT + Duration::from_secs(3) {
                break;
            }
        }
        let deadline = Instant::now() + Duration::from_secs(3);
        while srv.connections() > 0 && Instant::now() < deadline {
            std::thread::sleep(Duration::from_millis(20));
        }
        assert!(
            closed || srv.connections() == 0,
            "still served after {:?}",
            start.elapsed()
        );
        srv.stop(Duration::from_secs(2));
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(64))]
        /// Any bytes as a request get an answer or a closed connection, never a panic or a
        /// thread that stays.
        #[test]
        fn any_bytes_as_a_request_are_answered_or_dropped(
            bytes in proptest::collection::vec(proptest::prelude::any::<u8>(), 0..600),
            end in proptest::prelude::any::<bool>(),
        ) {
            let mut srv = served();
            let mut s = TcpStream::connect(srv.addr()).unwrap();
            s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
            let _ = s.write_all(&bytes);
            if end {
                let _ = s.write_all(b"\r\n\r\n");
            }
            let _ = s.shutdown(std::net::Shutdown::Write);
            let mut out = Vec::new();
            let _ = s.read_to_end(&mut out);
            proptest::prop_assert!(out.is_empty() || out.starts_with(b"HTTP/1.1 "));
            srv.stop(Duration::from_secs(2));
            proptest::prop_assert_eq!(srv.connections(), 0);
        }
    }
}
