//! The dashboard's HTTP/1.1 server, over `std::net`: GET and HEAD only, one request per
//! connection, and every cost a request can cause bounded before it is paid.
//!
//! - the request line and headers are read into one fixed buffer ([`MAX_HEAD`] bytes; the line
//!   itself at most [`MAX_REQUEST_LINE`], at most [`MAX_HEADERS`] headers): nothing a client
//!   declares is allocated;
//! - a request with a body (`Content-Length` above 0, any `Transfer-Encoding`) is refused unread;
//! - the request's head must arrive within [`HEAD_TIMEOUT`] in all (not per read, so a client
//!   sending a byte at a time cannot hold a thread), and the answer be taken within
//!   [`WRITE_TIMEOUT`];
//! - at most [`MAX_CONNECTIONS`] connections are served at once, each on a thread of its own; at
//!   the cap a new connection takes the slot of the oldest one still waiting for its request head
//!   after [`EVICT_AFTER`] (closed), so idle clients cannot starve a normal request; when no slot
//!   can be taken, it is answered 503 at once, without blocking the accepting thread;
//! - the `Host` header must name this server (a loopback name or address when it serves on
//!   loopback), so a page on another site that rebinds its DNS name to 127.0.0.1 cannot read
//!   the runs.

use super::discover::Roots;
use super::routes;
use crate::error::{Error, Result};
use std::io::{ErrorKind, Read, Write};
use std::net::{IpAddr, Shutdown, SocketAddr, TcpListener, TcpStream, ToSocketAddrs};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::time::{Duration, Instant};

/// The request line and headers together, in bytes: the size of each connection's buffer.
pub const MAX_HEAD: usize = 16 * 1024;
/// The request line, in bytes (414 beyond).
pub const MAX_REQUEST_LINE: usize = 8 * 1024;
/// Header lines per request (431 beyond).
pub const MAX_HEADERS: usize = 64;
/// Connections served at once: a few browser tabs and their polls need far fewer.
pub const MAX_CONNECTIONS: usize = 32;
/// Time for a request's whole head to arrive (408 after).
pub const HEAD_TIMEOUT: Duration = Duration::from_secs(10);
/// Time for a client to take the answer.
pub const WRITE_TIMEOUT: Duration = Duration::from_secs(30);
/// After an error answer, what is still read (and dropped) so that the client sees the answer
/// rather than a reset: this many bytes, for at most [`LINGER`].
const DRAIN: usize = 1 << 20;
const LINGER: Duration = Duration::from_secs(1);

/// The addresses `host` names (`[::1]`, `::1`, `127.1`, `localhost`, a name), with `port`.
pub fn resolve(host: &str, port: u16) -> Result<Vec<SocketAddr>> {
    let bare = host.strip_prefix('[').and_then(|h| h.strip_suffix(']')).unwrap_or(host);
    let addrs: Vec<SocketAddr> = (bare, port)
        .to_socket_addrs()
        .map_err(|e| Error::Usage(format!("--host {host}: not an address this machine can resolve ({e})")))?
        .collect();
    if addrs.is_empty() {
        return Err(Error::Usage(format!("--host {host}: resolves to no address")));
    }
    Ok(addrs)
}

/// Whether `ip` is a loopback address, an IPv4 one written as IPv6 (`::ffff:127.0.0.1`) included.
pub fn is_loopback(ip: IpAddr) -> bool {
    ip.to_canonical().is_loopback()
}

/// A bound listener and what its connections need.
pub struct Server {
    listener: TcpListener,
    shared: Arc<Shared>,
    stop: Arc<AtomicBool>,
    slots: Arc<Slots>,
}

/// The connections being served, oldest first.
#[derive(Default)]
struct Slots {
    held: std::sync::Mutex<Vec<Slot>>,
    next: AtomicUsize,
}

/// One connection being served.
struct Slot {
    id: usize,
    /// A handle on its socket, to close it when a newcomer takes its slot.
    stream: TcpStream,
    /// Still waiting for its request head: may be closed to free the slot.
    waiting: Arc<AtomicBool>,
    /// When it was accepted.
    since: Instant,
}

/// How long a connection may wait for its head before a newcomer at the cap may take its slot: a
/// burst of real requests is not closed under itself, while idle clients hold a slot this long.
pub const EVICT_AFTER: Duration = Duration::from_millis(200);

impl Slots {
    /// A slot for a new connection: a free one, else the oldest waiting one's (that connection
    /// closed), else none.
    fn take(&self, stream: &TcpStream) -> Option<(usize, Arc<AtomicBool>)> {
        let mut held = self.held.lock().unwrap_or_else(|p| p.into_inner());
        if held.len() >= MAX_CONNECTIONS {
            let oldest =
                held.iter().position(|s| s.waiting.load(Ordering::SeqCst) && s.since.elapsed() >= EVICT_AFTER)?;
            let _ = held.remove(oldest).stream.shutdown(Shutdown::Both);
        }
        let handle = stream.try_clone().ok()?;
        let id = self.next.fetch_add(1, Ordering::SeqCst);
        let waiting = Arc::new(AtomicBool::new(true));
        held.push(Slot { id, stream: handle, waiting: Arc::clone(&waiting), since: Instant::now() });
        Some((id, waiting))
    }

    fn free(&self, id: usize) {
        self.held.lock().unwrap_or_else(|p| p.into_inner()).retain(|s| s.id != id);
    }
}

struct Shared {
    roots: Roots,
    port: u16,
    /// The `--host` as given, lower case, without brackets: a name it may be reached by.
    given: String,
    /// Serving on loopback only: then only loopback names are valid `Host`s.
    loopback: bool,
}

impl Server {
    /// Binds the first address `host` resolves to.
    pub fn bind(roots: Roots, host: &str, port: u16) -> Result<Server> {
        let addrs = resolve(host, port)?;
        let listener =
            TcpListener::bind(&addrs[..]).map_err(|e| Error::Usage(format!("cannot listen on {host}:{port}: {e}")))?;
        let local = listener.local_addr().map_err(|e| Error::Usage(format!("{host}:{port}: {e}")))?;
        let given = host.trim_start_matches('[').trim_end_matches(']').to_ascii_lowercase();
        let shared = Shared { roots, port: local.port(), given, loopback: is_loopback(local.ip()) };
        Ok(Server {
            listener,
            shared: Arc::new(shared),
            stop: Arc::new(AtomicBool::new(false)),
            slots: Arc::new(Slots::default()),
        })
    }

    /// The address bound.
    pub fn local_addr(&self) -> SocketAddr {
        self.listener.local_addr().expect("a bound listener has an address")
    }

    /// Accepts connections until [`Server::stopper`]'s handle is called.
    pub fn run(&self) {
        for conn in self.listener.incoming() {
            if self.stop.load(Ordering::SeqCst) {
                break;
            }
            let stream = match conn {
                Ok(s) => s,
                // Out of descriptors, or a connection reset before it was taken: wait a moment
                // rather than spin.
                Err(_) => {
                    std::thread::sleep(Duration::from_millis(10));
                    continue;
                }
            };
            let Some((id, waiting)) = self.slots.take(&stream) else {
                refuse_busy(stream);
                continue;
            };
            let shared = Arc::clone(&self.shared);
            let slots = Arc::clone(&self.slots);
            let spawned = std::thread::Builder::new().name("dashboard-conn".into()).spawn(move || {
                serve(stream, &shared, &waiting);
                slots.free(id);
            });
            if spawned.is_err() {
                self.slots.free(id);
            }
        }
    }

    /// A handle that ends [`Server::run`] (it wakes the accepting thread with a connection).
    pub fn stopper(&self) -> impl Fn() + Send + 'static {
        let stop = Arc::clone(&self.stop);
        let mut addr = self.local_addr();
        if addr.ip().is_unspecified() {
            addr.set_ip(if addr.is_ipv4() { [127, 0, 0, 1].into() } else { std::net::Ipv6Addr::LOCALHOST.into() });
        }
        move || {
            stop.store(true, Ordering::SeqCst);
            let _ = TcpStream::connect_timeout(&addr, Duration::from_secs(1));
        }
    }
}

/// 503 without waiting on the client: one non-blocking write, then the connection is dropped.
/// What of the request has already arrived is read first (without waiting, at most
/// [`MAX_HEAD`] bytes): closing with it unread would reset the connection, and a client could
/// see the reset instead of the 503.
fn refuse_busy(mut s: TcpStream) {
    let _ = s.set_nonblocking(true);
    let mut out = head(503, "text/plain; charset=utf-8", 9, &[]);
    out.extend_from_slice(b"503 busy\n");
    let _ = s.write_all(&out);
    let _ = s.shutdown(Shutdown::Write);
    drain(&mut s, &mut [0u8; 4096], MAX_HEAD, None);
}

/// Reads and drops what the client still sends, at most `max` bytes, until `until` (with none,
/// on a non-blocking stream: what has arrived): closing with unread data would reset the
/// connection, and the client could lose the answer.
fn drain(s: &mut TcpStream, buf: &mut [u8], max: usize, until: Option<Instant>) {
    let mut drained = 0;
    while drained < max {
        if let Some(until) = until {
            let left = until.saturating_duration_since(Instant::now());
            if left.is_zero() || s.set_read_timeout(Some(left)).is_err() {
                break;
            }
        }
        match s.read(buf) {
            Ok(0) | Err(_) => break,
            Ok(k) => drained += k,
        }
    }
}

/// Why no request could be taken from a connection.
#[derive(Debug, PartialEq, Eq)]
enum Bad {
    /// The client went away or sent nothing: no answer.
    Gone,
    /// An answer with this status and reason.
    Status(u16, &'static str),
}

/// The request's head, read into `buf`: its length (up to and with the blank line).
fn read_head(s: &mut TcpStream, buf: &mut [u8]) -> std::result::Result<usize, Bad> {
    let deadline = Instant::now() + HEAD_TIMEOUT;
    let mut n: usize = 0;
    // Where the search for the blank line resumes: each byte is looked at once or so.
    let mut from = 0;
    loop {
        if let Some(i) = buf[from..n].windows(4).position(|w| w == b"\r\n\r\n") {
            return Ok(from + i + 4);
        }
        from = n.saturating_sub(3);
        if n > MAX_REQUEST_LINE && !buf[..n].contains(&b'\n') {
            return Err(Bad::Status(414, "request line too long"));
        }
        if n == buf.len() {
            return Err(Bad::Status(431, "request headers too large"));
        }
        let left = deadline.saturating_duration_since(Instant::now());
        if left.is_zero() {
            return Err(Bad::Status(408, "request took too long to arrive"));
        }
        let _ = s.set_read_timeout(Some(left));
        match s.read(&mut buf[n..]) {
            Ok(0) => return if n == 0 { Err(Bad::Gone) } else { Err(Bad::Status(400, "request cut short")) },
            Ok(k) => n += k,
            Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {
                return Err(Bad::Status(408, "request took too long to arrive"));
            }
            Err(e) if e.kind() == ErrorKind::Interrupted => {}
            Err(_) => return Err(Bad::Gone),
        }
    }
}

/// A request this server answers: its method and target, as sent.
#[derive(Debug, PartialEq, Eq)]
struct Request<'a> {
    method: &'a str,
    target: &'a str,
    host: Option<&'a str>,
}

/// The request line and headers; refuses anything with a body, repeated or malformed framing.
fn parse(head: &[u8]) -> std::result::Result<Request<'_>, Bad> {
    let bad = |why| Bad::Status(400, why);
    let text = std::str::from_utf8(head).map_err(|_| bad("request head is not text"))?;
    let mut lines = text.strip_suffix("\r\n\r\n").unwrap_or(text).split("\r\n");
    let first = lines.next().unwrap_or("");
    if first.len() > MAX_REQUEST_LINE {
        return Err(Bad::Status(414, "request line too long"));
    }
    let mut parts = first.split(' ');
    let (Some(method), Some(target), Some(version), None) = (parts.next(), parts.next(), parts.next(), parts.next())
    else {
        return Err(bad("malformed request line"));
    };
    if version != "HTTP/1.1" && version != "HTTP/1.0" {
        return Err(Bad::Status(505, "HTTP/1.0 and 1.1 only"));
    }
    if method != "GET" && method != "HEAD" {
        return Err(Bad::Status(405, "read-only: only GET"));
    }
    if !target.starts_with('/') {
        return Err(bad("the target must be a path"));
    }
    let mut host = None;
    for (i, line) in lines.enumerate() {
        if i >= MAX_HEADERS {
            return Err(Bad::Status(431, "too many headers"));
        }
        let Some((name, value)) = line.split_once(':') else { return Err(bad("malformed header")) };
        if name.is_empty() || name.contains([' ', '\t']) {
            return Err(bad("malformed header"));
        }
        let value = value.trim_matches([' ', '\t']);
        if name.eq_ignore_ascii_case("host") {
            if host.replace(value).is_some() {
                return Err(bad("more than one Host header"));
            }
        } else if name.eq_ignore_ascii_case("content-length") {
            match value.parse::<u64>() {
                Ok(0) => {}
                Ok(_) => return Err(bad("a GET or HEAD request has no body")),
                Err(_) => return Err(bad("malformed Content-Length")),
            }
        } else if name.eq_ignore_ascii_case("transfer-encoding") {
            return Err(bad("a GET or HEAD request has no body"));
        }
    }
    Ok(Request { method, target, host })
}

impl Shared {
    /// Whether a `Host` header names this server: its port, and a name it is reached by
    /// (`localhost`, the `--host` given, an address: only a loopback one when serving on
    /// loopback). A DNS name that rebinding points here is none of these.
    fn host_ok(&self, host: &str) -> bool {
        let (name, port) = if let Some(rest) = host.strip_prefix('[') {
            let Some((name, after)) = rest.split_once(']') else { return false };
            match after {
                "" => (name, None),
                p => match p.strip_prefix(':') {
                    Some(p) => (name, Some(p)),
                    None => return false,
                },
            }
        } else {
            match host.rsplit_once(':') {
                Some((n, p)) => (n, Some(p)),
                None => (host, None),
            }
        };
        let port_ok = match port {
            Some(p) => p.parse::<u16>() == Ok(self.port),
            None => self.port == 80,
        };
        let name = name.to_ascii_lowercase();
        let name_ok = name == "localhost"
            || name == self.given
            || name.parse::<IpAddr>().is_ok_and(|ip| !self.loopback || is_loopback(ip));
        port_ok && name_ok
    }
}

/// Answers one connection: one request, then the connection closes.
fn serve(mut s: TcpStream, shared: &Shared, waiting: &AtomicBool) {
    let _ = s.set_write_timeout(Some(WRITE_TIMEOUT));
    let _ = s.set_nodelay(true);
    let mut buf = vec![0u8; MAX_HEAD];
    let outcome = read_head(&mut s, &mut buf).and_then(|end| {
        // From here its slot is not given away: it is being answered.
        waiting.store(false, Ordering::SeqCst);
        let req = parse(&buf[..end])?;
        match req.host {
            Some(h) if shared.host_ok(h) => {}
            Some(_) => return Err(Bad::Status(403, "this Host is not the address the dashboard serves")),
            None => return Err(Bad::Status(400, "no Host header")),
        }
        Ok((req.method == "HEAD", routes::handle(&shared.roots, "GET", req.target)))
    });
    let (bytes, clean) = match outcome {
        Ok((head_only, reply)) => {
            let mut out = head(reply.status, reply.content_type, reply.body.len(), &[]);
            if !head_only {
                out.extend_from_slice(&reply.body);
            }
            (out, true)
        }
        Err(Bad::Gone) => return,
        Err(Bad::Status(status, why)) => {
            let body = format!("{status} {why}\n");
            let extra: &[(&str, &str)] = if status == 405 { &[("Allow", "GET, HEAD")] } else { &[] };
            let mut out = head(status, "text/plain; charset=utf-8", body.len(), extra);
            out.extend_from_slice(body.as_bytes());
            (out, false)
        }
    };
    let _ = s.write_all(&bytes);
    let _ = s.shutdown(Shutdown::Write);
    // The request's rest (after an error) is drained for a moment, into the same buffer.
    let until = Instant::now() + if clean { Duration::from_millis(200) } else { LINGER };
    drain(&mut s, &mut buf, DRAIN, Some(until));
}

/// A response's status line and headers (every response closes its connection).
fn head(status: u16, content_type: &str, len: usize, extra: &[(&str, &str)]) -> Vec<u8> {
    let reason = match status {
        200 => "OK",
        400 => "Bad Request",
        403 => "Forbidden",
        404 => "Not Found",
        405 => "Method Not Allowed",
        408 => "Request Timeout",
        414 => "URI Too Long",
        431 => "Request Header Fields Too Large",
        503 => "Service Unavailable",
        505 => "HTTP Version Not Supported",
        _ => "",
    };
    let mut h = format!(
        "HTTP/1.1 {status} {reason}\r\nContent-Type: {content_type}\r\nContent-Length: {len}\r\nConnection: close\r\n\
         Content-Security-Policy: default-src 'none'; script-src 'self'; style-src 'self'; img-src 'self'; connect-src 'self'\r\n\
         X-Content-Type-Options: nosniff\r\nCache-Control: no-store\r\n"
    );
    for (k, v) in extra {
        h.push_str(&format!("{k}: {v}\r\n"));
    }
    h.push_str("\r\n");
    h.into_bytes()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shared(given: &str, port: u16, loopback: bool) -> Shared {
        let roots = Roots::new(&[std::env::temp_dir()]).unwrap();
        Shared { roots, port, given: given.into(), loopback }
    }

    #[test]
    fn parse_refuses_bodies_and_malformed_framing() {
        let ok = parse(b"GET /a?b=1 HTTP/1.1\r\nHost: x:1\r\nContent-Length: 0\r\n\r\n").unwrap();
        assert_eq!(ok, Request { method: "GET", target: "/a?b=1", host: Some("x:1") });
        let status = |h: &[u8]| match parse(h) {
            Err(Bad::Status(s, _)) => s,
            other => panic!("{other:?}"),
        };
        assert_eq!(status(b"GET / HTTP/1.1\r\nContent-Length: 99999999999\r\n\r\n"), 400);
        assert_eq!(status(b"GET / HTTP/1.1\r\nTransfer-Encoding: chunked\r\n\r\n"), 400);
        assert_eq!(status(b"GET / HTTP/1.1\r\nContent-Length: -1\r\n\r\n"), 400);
        assert_eq!(status(b"GET / HTTP/1.1\r\nHost: a\r\nHost: b\r\n\r\n"), 400);
        assert_eq!(status(b"GET http://x/ HTTP/1.1\r\n\r\n"), 400);
        assert_eq!(status(b"GET / HTTP/2\r\n\r\n"), 505);
        assert_eq!(status(b"GET /\r\n\r\n"), 400);
        assert_eq!(status(b"POST / HTTP/1.1\r\nContent-Length: 5\r\n\r\n"), 405);
        assert_eq!(status(b"GET / HTTP/1.1\r\n folded\r\n\r\n"), 400);
        let many = format!("GET / HTTP/1.1\r\n{}\r\n", "X-A: 1\r\n".repeat(MAX_HEADERS + 1));
        assert_eq!(status(many.as_bytes()), 431);
    }

    #[test]
    fn only_names_of_this_server_are_valid_hosts() {
        let s = shared("127.0.0.1", 8377, true);
        for ok in ["127.0.0.1:8377", "localhost:8377", "LOCALHOST:8377", "[::1]:8377", "127.1.2.3:8377"] {
            assert!(s.host_ok(ok), "{ok}");
        }
        for bad in ["evil.example:8377", "127.0.0.1:80", "127.0.0.1", "10.0.0.1:8377", "[::1", "localhost:x", ""] {
            assert!(!s.host_ok(bad), "{bad}");
        }
        assert!(s.host_ok("[::ffff:127.0.0.1]:8377"), "an IPv4 loopback written as IPv6");
        // Served on another address: that name, and addresses, but still no other DNS name.
        let s = shared("box.lan", 80, false);
        assert!(s.host_ok("box.lan") && s.host_ok("192.168.1.5") && s.host_ok("box.lan:80"));
        assert!(!s.host_ok("rebound.example"));
    }

    #[test]
    fn resolve_takes_brackets_and_short_forms() {
        let ip = |h: &str| resolve(h, 1).unwrap()[0].ip();
        assert_eq!(ip("[::1]"), "::1".parse::<IpAddr>().unwrap());
        assert_eq!(ip("127.1"), "127.0.0.1".parse::<IpAddr>().unwrap());
        assert!(is_loopback(ip("::ffff:127.0.0.1")) && is_loopback(ip("127.1")));
        assert!(!is_loopback("192.0.2.1".parse().unwrap()));
        assert!(resolve("no such host.invalid", 1).is_err());
    }
}
