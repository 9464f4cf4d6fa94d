//! The commands behind the binary: the command line (`args`), the commands that run a session
//! (`acquisition`: run, check, replay, lockstep) and those that read files and print
//! (`analysis`: average, compare, report, plan, alarms, export), the exit codes (`exit`), and what they are
//! made of: decoding and averaging files and the plan (`commands`), cross-validation against a
//! reference (`compare`), the lab's exports (`export`), the end-of-run report (`report`) and the summary printed at the end
//! of a run or replay (`summary`). `main` only sets up logging and maps an error to its code.

mod acquisition;
mod analysis;
pub mod args;
pub(crate) mod brdf_plots;
pub(crate) mod commands;
pub(crate) mod compare;
pub mod exit;
pub mod export;
pub(crate) mod report;
pub(crate) mod summary;

use anyhow::Result;
use args::{Cli, Command};
use std::process::ExitCode;

/// Carry out the command; its output goes to standard output.
pub fn run(cli: Cli) -> Result<ExitCode> {
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    match cli.command {
        Command::Average(a) => analysis::average_command(a, &mut out),
        Command::Compare(a) => analysis::compare_command(a, &mut out),
        Command::Report(a) => analysis::report_command(a, &mut out),
        Command::Plan(a) => analysis::plan_command(a, &mut out),
        Command::Alarms(a) => analysis::alarms_command(a, &mut out),
        Command::Export(a) => analysis::export_command(a, &mut out),
        Command::Run(a) => acquisition::run_command(a, &mut out),
        Command::Replay(a) => acquisition::replay_command(a, &mut out),
        Command::Check(a) => acquisition::check_command(a, &mut out),
        Command::Lockstep(a) => acquisition::lockstep_command(a, &mut out),
    }
}
