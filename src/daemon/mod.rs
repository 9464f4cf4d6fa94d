//! The daemon shell: everything that touches tokio, the serial port, files and the terminal.
//! The decisions are the engine's (`crate::engine`); this module moves bytes and records.

pub mod archive;
pub mod http;
pub mod ingest;
pub mod link;
pub mod lockstep;
pub mod replay;
pub mod run;
pub(crate) mod sinks;
pub mod status;
