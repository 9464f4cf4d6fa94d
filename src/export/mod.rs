//! The export's pure core: what a lab takes away from a checked session.
//!
//! - [`correction`]: the drift model an export divides out (the session's end-of-run gain and
//!   lamp-colour estimates) and the photometry that turns a capture's XYZ into a BRDF in sr⁻¹
//!   relative to the configured white.
//! - [`table`]: one row per capture, raw and corrected, with the factors that divide the drift
//!   out of its image (the `table` format, CSV and JSON lines with the same columns).
//! - [`merl`]: the MERL binary layout (90 × 90 × 180 cells over θh, θd, φd) filled by the
//!   layered resampler of `measure::resample` (the paper's mirror-aligned parameterisation,
//!   Renka's modified Shepard interpolation), with each cell's state and σ.
//!
//! Nothing here reads a file or a clock: the shell (`cli::export`) reads the session, calls
//! these, and writes the outputs.

pub mod correction;
pub mod merl;
pub mod table;

use thiserror::Error;

/// Why an export cannot be made.
#[derive(Debug, Error, PartialEq)]
pub enum ExportError {
    #[error("the configured white has no usable RGB (its XYZ converts to {0:?}): the BRDF cannot be put on its scale")]
    BadWhite([f64; 3]),
    #[error("the white's reflectance {0} is not positive and finite")]
    BadReflectance(f64),
    #[error("the RGB scale {0} is not positive and finite")]
    BadScale(f64),
    #[error("the primaries' matrix cannot be inverted")]
    SingularPrimaries,
    #[error("no capture can be exported: {0}")]
    NothingToExport(String),
}
