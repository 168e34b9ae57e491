//! `bfqi-ga dashboard`: the arguments, the safety checks on them, and the call into the library.

use super::Outcome;
use crate::dashboard::{Dashboard, Options, is_loopback};
use anyhow::Result;
use clap::Args;
use std::io::Write;
use std::path::PathBuf;

/// `bfqi-ga dashboard`.
#[derive(Debug, Args)]
pub struct DashboardArgs {
    /// Folders whose run directories are served (default: results).
    #[arg(default_value = "results")]
    pub dirs: Vec<PathBuf>,
    /// Port to listen on (0: any free port; the URL printed says which).
    #[arg(long, default_value_t = 8377)]
    pub port: u16,
    /// Address to listen on. Anything but a loopback address exposes the runs to the network.
    #[arg(long, default_value = "127.0.0.1")]
    pub host: String,
}

pub(super) fn dashboard(a: DashboardArgs) -> Result<Outcome> {
    for d in &a.dirs {
        anyhow::ensure!(d.is_dir(), "{}: no such directory", d.display());
    }
    let host = a.host.clone();
    let d = Dashboard::bind(&Options { roots: a.dirs, host: a.host, port: a.port })?;
    // Said once bound: an address that cannot be served is refused without a word of serving.
    if !is_loopback(&host) {
        eprintln!("warning: serving on {host}: anyone who can reach this address can read these runs (read-only)");
    }
    println!("bfqi-ga dashboard: {}", d.url());
    std::io::stdout().flush()?;
    d.run();
    Ok(Outcome::Success)
}
