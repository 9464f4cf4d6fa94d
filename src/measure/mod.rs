//! The measurement core: pure, deterministic, sans-IO.
//!
//! Nothing in this module reads a clock, a file, a port or the environment. Time arrives as data
//! (controller timestamps), pixels arrive as decoded buffers, and every function returns typed
//! errors (`thiserror`). The shell (`crate::decode`, `crate::daemon`, `crate::cli`) does
//! the I/O and feeds this module. Replaying the same inputs gives the same bytes out.

pub mod averaging;
pub mod colour;
pub mod crossval;
pub mod geometry;
pub mod kinematics;
pub mod plan;
pub mod reciprocity;
pub mod resample;
pub mod shepard;
pub(crate) mod smooth_brdf;
pub(crate) mod stats;
pub(crate) mod timeline;
