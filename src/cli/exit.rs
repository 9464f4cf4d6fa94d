//! Exit codes (docs/commands.md's table) and how an error maps to one.

use std::process::ExitCode;

/// Some captures named on the command line could not be decoded (`average`).
pub(crate) const EXIT_FILE_FAILED: u8 = 1;
/// A usage or configuration error, or malformed input named on the command line.
pub(crate) const EXIT_USAGE: u8 = 2;
/// Anything else that failed at run time.
pub(crate) const EXIT_RUNTIME: u8 = 3;
/// The run raised a critical alarm.
pub(crate) const EXIT_CRITICAL: u8 = 4;
/// A replay did not reproduce the recorded results.
pub(crate) const EXIT_REPLAY_MISMATCH: u8 = 5;
/// `check` and watch mode: the result is empty or meaningless (`cli::summary::meaningless`).
pub(crate) const EXIT_MEANINGLESS: u8 = 6;

/// A mistake in how the command was called (exit status 2).
#[derive(Debug)]
pub(crate) struct UsageError(pub String);

impl std::fmt::Display for UsageError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for UsageError {}

/// The exit status of a command that failed: usage, configuration, a files source's sidecar
/// and pattern, and malformed input files named on the command line are 2; anything else at
/// run time is 3.
pub fn for_error(e: &anyhow::Error) -> ExitCode {
    let usage = e.chain().any(|c| {
        c.downcast_ref::<crate::config::ConfigError>().is_some()
            || c.downcast_ref::<crate::reference::ReferenceError>().is_some()
            || c.downcast_ref::<UsageError>().is_some()
            || c.downcast_ref::<crate::detect::probe_plan::ProbePlanError>().is_some()
            // a sidecar table that does not parse, or a pattern and order that cannot place
            // anything: the configuration's input, as a config error is
            || c.downcast_ref::<crate::archive::listing::ListingError>().is_some()
    });
    ExitCode::from(if usage { EXIT_USAGE } else { EXIT_RUNTIME })
}
