//! The `bfqi-ga` binary: parse arguments, call the library, map errors to exit codes
//! (0 success, 1 a run failed or a check disagreed, 2 bad input).

use clap::Parser;
use std::process::ExitCode;

fn main() -> ExitCode {
    let cli = bfqi_ga::cli::Cli::parse();
    match bfqi_ga::cli::run(cli) {
        Ok(code) => code,
        Err(e) => {
            // One line: the chain of contexts, outermost first.
            eprintln!("error: {e:#}");
            ExitCode::from(2)
        }
    }
}
