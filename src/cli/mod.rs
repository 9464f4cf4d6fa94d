//! The commands behind the CLI, apart from `run` and `replay` (the daemon's): decoding and
//! averaging files (`average`, `plan`), cross-validation against a reference (`compare`), the
//! end-of-run report (`report`), and the summary printed at the end of a run or replay. They
//! read and write files and return records; argument parsing and exit codes are `main`'s.

pub mod commands;
pub mod compare;
pub mod report;
pub mod summary;
