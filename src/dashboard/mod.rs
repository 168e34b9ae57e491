//! `bfqi-ga dashboard`: a read-only local web view of the run directories under some folders.
//!
//! - [`discover`]: the served roots, the runs under them, and path resolution (traversal refused);
//! - [`search`] and [`runs`]: what each page reads, from the runs' small files (a setting's page
//!   reads that setting's units only);
//! - [`table`]: tables as escaped HTML, CSV and JSON; [`html`]: escaping and the page layout;
//! - [`routes`]: requests to responses; here, the HTTP server (`tiny_http`, synchronous: a local
//!   viewer needs no async runtime) and its worker threads.
//!
//! Charts are drawn in the browser as inline SVG by a small embedded script (`assets/app.js`),
//! which polls the page's JSON every 2 s and redraws without a reload. Nothing comes from outside.

pub mod discover;
pub mod html;
pub mod routes;
pub mod runs;
pub mod search;
pub mod table;

use crate::error::{Error, Result};
use discover::Roots;
use std::path::PathBuf;
use std::sync::Arc;

/// Where and what to serve.
#[derive(Debug, Clone)]
pub struct Options {
    /// Folders whose run directories are served.
    pub roots: Vec<PathBuf>,
    /// Address to bind (127.0.0.1 unless asked otherwise).
    pub host: String,
    /// Port (0: any free one).
    pub port: u16,
}

/// A bound dashboard.
pub struct Dashboard {
    server: Arc<tiny_http::Server>,
    roots: Arc<Roots>,
    url: String,
}

/// Threads answering requests: a page and its polls, images, and a second browser tab at once.
const WORKERS: usize = 4;

impl Dashboard {
    /// Binds the address; missing roots and an address that cannot be bound are refused.
    pub fn bind(opts: &Options) -> Result<Dashboard> {
        let roots = Roots::new(&opts.roots)?;
        let server = tiny_http::Server::http((opts.host.as_str(), opts.port))
            .map_err(|e| Error::Usage(format!("cannot listen on {}:{}: {e}", opts.host, opts.port)))?;
        let port = server.server_addr().to_ip().map_or(opts.port, |a| a.port());
        let host = if opts.host.contains(':') { format!("[{}]", opts.host) } else { opts.host.clone() };
        Ok(Dashboard { server: Arc::new(server), roots: Arc::new(roots), url: format!("http://{host}:{port}/") })
    }

    /// The URL it serves at.
    pub fn url(&self) -> &str {
        &self.url
    }

    /// Serves until [`Dashboard::stop`] (from another thread) or for ever.
    pub fn run(&self) {
        std::thread::scope(|s| {
            for _ in 0..WORKERS {
                s.spawn(|| {
                    while let Ok(req) = self.server.recv() {
                        answer(&self.roots, req);
                    }
                });
            }
        });
    }

    /// A handle that stops [`Dashboard::run`].
    pub fn stopper(&self) -> impl Fn() + Send + 'static {
        let server = Arc::clone(&self.server);
        move || {
            for _ in 0..WORKERS {
                server.unblock();
            }
        }
    }
}

fn answer(roots: &Roots, req: tiny_http::Request) {
    let method = req.method().as_str().to_string();
    let reply = routes::handle(roots, &method, req.url());
    let header = |k: &str, v: &str| tiny_http::Header::from_bytes(k.as_bytes(), v.as_bytes()).expect("valid header");
    let response = tiny_http::Response::from_data(reply.body)
        .with_status_code(reply.status)
        .with_header(header("Content-Type", reply.content_type))
        // Only this server's own script and images; nothing inline, nothing from elsewhere.
        .with_header(header(
            "Content-Security-Policy",
            "default-src 'none'; script-src 'self'; style-src 'self'; img-src 'self'; connect-src 'self'",
        ))
        .with_header(header("X-Content-Type-Options", "nosniff"))
        .with_header(header("Cache-Control", "no-store"));
    let _ = req.respond(response); // a browser that went away
}

/// Whether `host` is a loopback address (anything else needs the flag and gets a warning).
pub fn is_loopback(host: &str) -> bool {
    host == "localhost" || host.parse::<std::net::IpAddr>().is_ok_and(|a| a.is_loopback())
}
