//! The session folder and what is made from it: its files and their one reader (`folder`), the
//! checksummed journal (`journal`), and opening, refusing and rebuilding a session
//! (`recovery`). No tokio, no serial port: the run loop and replay drive these.

pub mod folder;
pub mod journal;
pub mod recovery;
