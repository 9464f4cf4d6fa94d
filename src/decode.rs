//! Shell: decoding one HDR capture (Radiance `.hdr` via `image`, OpenEXR via `exr`) from its
//! bytes into an interleaved linear RGB f32 buffer for the measurement core.
//!
//! Hardening, because one bad file must never stop a 13-hour run:
//! - the format is sniffed from the magic bytes, not trusted from the name;
//! - image dimensions are checked against [`DecodeLimits`] before any pixel buffer is allocated
//!   (EXR: from the header; Radiance: `image::Limits` on a `BufReader`);
//! - the `exr` decoder runs `.non_parallel()` (its thread pool can abort the process on a
//!   malformed file) and every decoder call runs under `catch_unwind`, so a decoder panic
//!   becomes [`DecodeError::Panicked`].

use crate::measure::averaging::RgbView;
use std::io::{BufReader, Cursor};
use std::panic::{catch_unwind, AssertUnwindSafe};
use thiserror::Error;

#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum CaptureFormat {
    Hdr,
    Exr,
}

#[derive(Debug, Error, PartialEq)]
pub enum DecodeError {
    #[error("file is empty")]
    Empty,
    #[error("not a Radiance .hdr or OpenEXR file (magic bytes {0:02x?})")]
    UnknownFormat(Vec<u8>),
    #[error("Radiance decoder: {0}")]
    Hdr(String),
    #[error("OpenEXR decoder: {0}")]
    Exr(String),
    #[error("OpenEXR file has no layer with R, G and B channels (channels: {0})")]
    NoRgbLayer(String),
    #[error("OpenEXR deep data is not supported")]
    DeepData,
    #[error("image {width}×{height} exceeds the limit of {max_pixels} pixels")]
    TooLarge {
        width: usize,
        height: usize,
        max_pixels: usize,
    },
    #[error("decoder panicked (malformed file): {0}")]
    Panicked(String),
}

/// Bounds on what a decoder may allocate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DecodeLimits {
    pub max_pixels: usize,
    pub max_dimension: u32,
}

impl Default for DecodeLimits {
    fn default() -> Self {
        // 64 MP is 20× a UBO capture; 768 MiB of f32 RGB at most.
        DecodeLimits {
            max_pixels: 64 << 20,
            max_dimension: 32768,
        }
    }
}

/// A decoded capture.
#[derive(Debug, Clone, PartialEq)]
pub struct DecodedImage {
    pub format: CaptureFormat,
    pub width: usize,
    pub height: usize,
    /// Interleaved RGB, row-major, top row first.
    pub data: Vec<f32>,
}

impl DecodedImage {
    pub fn view(&self) -> RgbView<'_> {
        RgbView {
            width: self.width,
            height: self.height,
            data: &self.data,
        }
    }
}

/// Sniff the format from the first bytes.
pub fn detect_format(bytes: &[u8]) -> Result<CaptureFormat, DecodeError> {
    if bytes.is_empty() {
        return Err(DecodeError::Empty);
    }
    if bytes.starts_with(&[0x76, 0x2f, 0x31, 0x01]) {
        return Ok(CaptureFormat::Exr);
    }
    if bytes.starts_with(b"#?") {
        return Ok(CaptureFormat::Hdr);
    }
    Err(DecodeError::UnknownFormat(bytes[..bytes.len().min(8)].to_vec()))
}

fn panic_message(p: Box<dyn std::any::Any + Send>) -> String {
    if let Some(s) = p.downcast_ref::<&str>() {
        (*s).to_string()
    } else if let Some(s) = p.downcast_ref::<String>() {
        s.clone()
    } else {
        "unknown panic payload".to_string()
    }
}

/// Decode a capture from its bytes. Never panics.
pub fn decode(bytes: &[u8], limits: &DecodeLimits) -> Result<DecodedImage, DecodeError> {
    let format = detect_format(bytes)?;
    let result = catch_unwind(AssertUnwindSafe(|| match format {
        CaptureFormat::Hdr => decode_hdr(bytes, limits),
        CaptureFormat::Exr => decode_exr(bytes, limits),
    }));
    match result {
        Ok(r) => r,
        Err(p) => Err(DecodeError::Panicked(panic_message(p))),
    }
}

fn check_size(width: usize, height: usize, limits: &DecodeLimits) -> Result<(), DecodeError> {
    let too_large = || DecodeError::TooLarge {
        width,
        height,
        max_pixels: limits.max_pixels,
    };
    if width > limits.max_dimension as usize || height > limits.max_dimension as usize {
        return Err(too_large());
    }
    match width.checked_mul(height) {
        Some(n) if n <= limits.max_pixels => Ok(()),
        _ => Err(too_large()),
    }
}

fn decode_hdr(bytes: &[u8], limits: &DecodeLimits) -> Result<DecodedImage, DecodeError> {
    use image::codecs::hdr::HdrDecoder;
    use image::ImageDecoder;
    let reader = BufReader::new(Cursor::new(bytes));
    let mut dec = HdrDecoder::new(reader).map_err(|e| DecodeError::Hdr(e.to_string()))?;
    let (w, h) = dec.dimensions();
    check_size(w as usize, h as usize, limits)?;
    let mut lim = image::Limits::default();
    lim.max_image_width = Some(limits.max_dimension);
    lim.max_image_height = Some(limits.max_dimension);
    lim.max_alloc = Some((limits.max_pixels as u64) * 12 + (1 << 20));
    dec.set_limits(lim).map_err(|e| DecodeError::Hdr(e.to_string()))?;
    let n = (w as usize) * (h as usize) * 3;
    let mut data = vec![0f32; n];
    dec.read_image(bytemuck::cast_slice_mut(&mut data))
        .map_err(|e| DecodeError::Hdr(e.to_string()))?;
    Ok(DecodedImage {
        format: CaptureFormat::Hdr,
        width: w as usize,
        height: h as usize,
        data,
    })
}

struct ExrRgb {
    width: usize,
    data: Vec<f32>,
}

fn decode_exr(bytes: &[u8], limits: &DecodeLimits) -> Result<DecodedImage, DecodeError> {
    use exr::prelude::*;
    let meta = exr::meta::MetaData::read_from_buffered(Cursor::new(bytes), false)
        .map_err(|e| DecodeError::Exr(e.to_string()))?;
    let has = |hd: &exr::meta::header::Header, n: &str| hd.channels.list.iter().any(|c| c.name.eq(n));
    let rgb_header = meta
        .headers
        .iter()
        .find(|hd| has(hd, "R") && has(hd, "G") && has(hd, "B"));
    let Some(header) = rgb_header else {
        let names: Vec<String> = meta
            .headers
            .iter()
            .flat_map(|hd| hd.channels.list.iter().map(|c| c.name.to_string()))
            .collect();
        return Err(DecodeError::NoRgbLayer(names.join(", ")));
    };
    if header.deep {
        return Err(DecodeError::DeepData);
    }
    check_size(header.layer_size.0, header.layer_size.1, limits)?;

    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .rgb_channels(
            |size: Vec2<usize>, _: &RgbChannels| ExrRgb {
                width: size.0,
                data: vec![0f32; size.0 * size.1 * 3],
            },
            |px: &mut ExrRgb, pos: Vec2<usize>, (r, g, b): (f32, f32, f32)| {
                let i = (pos.1 * px.width + pos.0) * 3;
                if let Some(dst) = px.data.get_mut(i..i + 3) {
                    dst.copy_from_slice(&[r, g, b]);
                }
            },
        )
        .first_valid_layer()
        .all_attributes()
        .non_parallel()
        .from_buffered(Cursor::new(bytes))
        .map_err(|e| DecodeError::Exr(e.to_string()))?;
    let layer = image.layer_data;
    let (w, h) = (layer.size.0, layer.size.1);
    Ok(DecodedImage {
        format: CaptureFormat::Exr,
        width: w,
        height: h,
        data: layer.channel_data.pixels.data,
    })
}
