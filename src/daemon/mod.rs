//! The daemon shell: everything that touches tokio, the serial port, files and the terminal.
//! The decisions are the engine's (`crate::engine`); this module moves bytes and records.

pub(crate) mod archive;
pub(crate) mod http;
pub mod ingest;
pub(crate) mod link;
pub(crate) mod lockstep;
pub mod replay;
pub(crate) mod run;
pub(crate) mod scale;
pub(crate) mod sinks;
pub(crate) mod status;
