//! The `goniowatch` binary: logging, the command line, and the exit status. The commands are
//! in the library's `cli`.

use clap::Parser;
use goniowatch::cli::args::Cli;
use std::process::ExitCode;

fn init_logging() {
    let filter = tracing_subscriber::EnvFilter::try_from_env("GONIOWATCH_LOG")
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("warn"));
    tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .init();
    // Route panics to the log. A decoder panic is also caught and reported as a typed error.
    std::panic::set_hook(Box::new(|info| {
        tracing::error!(target: "goniowatch::panic", "panic: {info}");
    }));
}

fn main() -> ExitCode {
    init_logging();
    let cli = Cli::parse();
    match goniowatch::cli::run(cli) {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e:#}");
            goniowatch::cli::exit::for_error(&e)
        }
    }
}
