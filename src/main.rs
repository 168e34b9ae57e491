//! The `bfqi-ga` binary: parse arguments, call the library, and decide the exit code of every
//! ending (0 success, 1 a run failed or a check disagreed, 2 bad input, 130 stopped by Ctrl-C).

use bfqi_ga::cli::Outcome;
use clap::Parser;
use std::process::ExitCode;

fn main() -> ExitCode {
    keep_freed_memory();
    let cli = match bfqi_ga::cli::Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) if !e.use_stderr() => e.exit(), // --help, --version
        Err(e) => {
            // One line, as every other refusal: the error and its tip, without the usage block.
            let text = e.to_string();
            let keep: Vec<&str> = text
                .lines()
                .map(str::trim)
                .take_while(|l| !l.starts_with("Usage:"))
                .filter(|l| !l.is_empty())
                .collect();
            eprintln!("{} (see bfqi-ga --help)", keep.join("; "));
            return ExitCode::from(2);
        }
    };
    match bfqi_ga::cli::run(cli) {
        Ok(Outcome::Success) => ExitCode::SUCCESS,
        Ok(Outcome::Failed) => ExitCode::from(1),
        // 128 + SIGINT, as a shell reports a command Ctrl-C ended.
        Ok(Outcome::Interrupted) => ExitCode::from(130),
        Err(e) => {
            // One line: the chain of contexts, outermost first, with control characters (from a
            // damaged file's strings) escaped, so none can break the line or reach the terminal.
            eprintln!("error: {}", escape_controls(&format!("{e:#}")));
            ExitCode::from(exit_code(&e))
        }
    }
}

/// `text` with every control character written as its escape (`\n`, `\u{7}`).
fn escape_controls(text: &str) -> String {
    text.chars().map(|c| if c.is_control() { c.escape_default().to_string() } else { c.to_string() }).collect()
}

/// The exit code of an error, decided here for every command: 1 when a run failed or a check
/// disagreed, 2 for bad input (everything else the library refuses).
fn exit_code(e: &anyhow::Error) -> u8 {
    match e.downcast_ref::<bfqi_ga::Error>() {
        Some(bfqi_ga::Error::Failed(_)) => 1,
        // A full disk is the run failing, not the user's input; the run resumes once there is room.
        Some(bfqi_ga::Error::Io { err, .. }) if err.kind() == std::io::ErrorKind::StorageFull => 1,
        _ => 2,
    }
}

/// FQI allocates the same large buffers every iteration (tree workspaces, per-tree leaf indices,
/// padded states). glibc serves blocks above 128 KiB from fresh `mmap`s and unmaps them on free, so
/// each iteration paid its memory again in page faults (a 2000-episode pendulum run: 0.5 M faults,
/// 1.2 s of kernel time). Served from the heap and kept there, they are reused.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
fn keep_freed_memory() {
    // SAFETY: mallopt only changes allocator parameters, here before any other thread exists.
    unsafe {
        // 32 MiB is the largest threshold glibc accepts on 64-bit targets.
        libc::mallopt(libc::M_MMAP_THRESHOLD, 32 << 20);
        libc::mallopt(libc::M_TRIM_THRESHOLD, i32::MAX);
    }
}

#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
fn keep_freed_memory() {}
