//! `bfqi-ga dashboard`: a read-only local web view of the run directories under some folders.
//!
//! - [`discover`]: the served roots, the runs under them, and path resolution (traversal refused);
//! - [`search`] and [`runs`]: what each page reads, from the runs' small files (a setting's page
//!   reads that setting's units only);
//! - [`pair`]: two runs side by side (`/compare-runs`);
//! - [`table`]: tables as escaped HTML, CSV and JSON; [`html`]: escaping and the page layout;
//! - [`routes`]: requests to responses; [`server`]: the HTTP/1.1 server over `std::net` (GET
//!   only, one request a connection, every allocation a request can cause bounded).
//!
//! Charts are drawn in the browser as inline SVG by a small embedded script (`assets/app.js`),
//! which polls the page's JSON every 2 s and redraws without a reload. Nothing comes from outside.

pub mod discover;
pub mod html;
pub mod pair;
pub mod routes;
pub mod runs;
pub mod search;
pub mod server;
pub mod table;

use crate::error::Result;
use discover::Roots;
use std::path::PathBuf;

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
    server: server::Server,
    url: String,
}

impl Dashboard {
    /// Binds the address; missing roots and an address that cannot be resolved or bound are
    /// refused.
    pub fn bind(opts: &Options) -> Result<Dashboard> {
        let roots = Roots::new(&opts.roots)?;
        let server = server::Server::bind(roots, &opts.host, opts.port)?;
        let url = format!("http://{}/", server.local_addr());
        Ok(Dashboard { server, url })
    }

    /// The URL it serves at.
    pub fn url(&self) -> &str {
        &self.url
    }

    /// Whether it serves on a loopback address only.
    pub fn is_loopback(&self) -> bool {
        server::is_loopback(self.server.local_addr().ip())
    }

    /// Serves until [`Dashboard::stopper`]'s handle is called (from another thread) or for ever.
    pub fn run(&self) {
        self.server.run();
    }

    /// A handle that stops [`Dashboard::run`].
    pub fn stopper(&self) -> impl Fn() + Send + 'static {
        self.server.stopper()
    }
}

/// Whether every address `host` resolves to is a loopback one (anything else needs the flag and
/// gets a warning); `127.1`, `[::1]` and `::ffff:127.0.0.1` are loopback too.
pub fn is_loopback(host: &str) -> bool {
    server::resolve(host, 0).is_ok_and(|a| a.iter().all(|a| server::is_loopback(a.ip())))
}
