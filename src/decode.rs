//! Shell: decoding one HDR capture (Radiance `.hdr` via `image`, OpenEXR via `exr`) from its
//! bytes into an interleaved linear RGB f32 buffer for the measurement core.
//!
//! Hardening, because one bad file must never stop a 13-hour run:
//! - the format is sniffed from the magic bytes, not trusted from the name;
//! - image dimensions are checked against [`DecodeLimits`] before any pixel buffer is allocated
//!   (EXR: from the header; Radiance: `image::Limits` on a `BufReader`);
//! - `exr`'s own parallel decoder (whose thread pool can abort the process on a malformed file)
//!   is never used. With one thread (`DecodeLimits::threads`, the default, for a worker pool
//!   that decodes several captures at once) `exr` reads `.non_parallel()`; with more, the chunks
//!   are decompressed on our own scoped threads, each under `catch_unwind`. The whole decoder
//!   call runs under `catch_unwind` too, so a decoder panic becomes [`DecodeError::Panicked`].
//!   A file with missing chunks is an error, not a half-black image.

use crate::measure::averaging::{Layout, RgbView};
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
    /// Threads for OpenEXR block decompression (our own scoped threads, not exr's pool).
    /// 1 inside a worker pool that already decodes several captures at once.
    pub threads: usize,
}

impl Default for DecodeLimits {
    fn default() -> Self {
        // 64 MP is 20× a UBO capture; 768 MiB of f32 RGB at most.
        DecodeLimits {
            max_pixels: 64 << 20,
            max_dimension: 32768,
            threads: 1,
        }
    }
}

/// Decoded pixels, in the layout the decoder produces (no copy to reshape them).
#[derive(Debug, Clone, PartialEq)]
pub enum Pixels {
    /// Interleaved RGB, row-major, top row first (Radiance).
    Interleaved(Vec<f32>),
    /// R, G and B planes, row-major, top row first (OpenEXR).
    Planar([Vec<f32>; 3]),
}

/// A decoded capture.
#[derive(Debug, Clone, PartialEq)]
pub struct DecodedImage {
    pub format: CaptureFormat,
    pub width: usize,
    pub height: usize,
    pub pixels: Pixels,
}

impl DecodedImage {
    pub fn view(&self) -> RgbView<'_> {
        let layout = match &self.pixels {
            Pixels::Interleaved(d) => Layout::Interleaved(d),
            Pixels::Planar([r, g, b]) => Layout::Planar(r, g, b),
        };
        RgbView {
            width: self.width,
            height: self.height,
            layout,
        }
    }

    /// The pixel at (x, y) as (R, G, B).
    pub fn pixel(&self, x: usize, y: usize) -> Option<[f32; 3]> {
        if x >= self.width || y >= self.height {
            return None;
        }
        let i = y * self.width + x;
        match &self.pixels {
            Pixels::Interleaved(d) => d.get(i * 3..i * 3 + 3).map(|p| [p[0], p[1], p[2]]),
            Pixels::Planar([r, g, b]) => Some([*r.get(i)?, *g.get(i)?, *b.get(i)?]),
        }
    }

    /// Every channel value, for whole-image checks.
    pub fn samples(&self) -> Box<dyn Iterator<Item = f32> + '_> {
        match &self.pixels {
            Pixels::Interleaved(d) => Box::new(d.iter().copied()),
            Pixels::Planar([r, g, b]) => Box::new(r.iter().chain(g).chain(b).copied()),
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
    Err(DecodeError::UnknownFormat(
        bytes[..bytes.len().min(8)].to_vec(),
    ))
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
    dec.set_limits(lim)
        .map_err(|e| DecodeError::Hdr(e.to_string()))?;
    let n = (w as usize) * (h as usize) * 3;
    let mut data = vec![0f32; n];
    dec.read_image(bytemuck::cast_slice_mut(&mut data))
        .map_err(|e| DecodeError::Hdr(e.to_string()))?;
    Ok(DecodedImage {
        format: CaptureFormat::Hdr,
        width: w as usize,
        height: h as usize,
        pixels: Pixels::Interleaved(data),
    })
}

/// Convert one line of little-endian samples to f32. f16 goes through `half`'s slice
/// conversion, which uses the CPU's F16C instructions when it has them.
fn line_to_f32(
    bytes: &[u8],
    n: usize,
    sample_type: exr::meta::attribute::SampleType,
) -> Result<Vec<f32>, DecodeError> {
    use exr::meta::attribute::SampleType;
    let size = match sample_type {
        SampleType::F16 => 2,
        SampleType::F32 | SampleType::U32 => 4,
    };
    if bytes.len() != n * size {
        return Err(DecodeError::Exr(format!(
            "line has {} bytes, expected {}",
            bytes.len(),
            n * size
        )));
    }
    Ok(match sample_type {
        SampleType::F32 => bytes
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect(),
        SampleType::U32 => bytes
            .chunks_exact(4)
            .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]) as f32)
            .collect(),
        SampleType::F16 => {
            let halves: Vec<half::f16> = bytes
                .chunks_exact(2)
                .map(|c| half::f16::from_bits(u16::from_le_bytes([c[0], c[1]])))
                .collect();
            let mut v = vec![0f32; n];
            half::slice::HalfFloatSliceExt::convert_to_f32_slice(halves.as_slice(), &mut v);
            v
        }
    })
}

/// One decoded row segment of one channel: (channel slot 0..3, first sample index, samples).
type Segment = (usize, usize, Vec<f32>);

fn decode_exr(bytes: &[u8], limits: &DecodeLimits) -> Result<DecodedImage, DecodeError> {
    let meta = exr::meta::MetaData::read_from_buffered(Cursor::new(bytes), false)
        .map_err(|e| DecodeError::Exr(e.to_string()))?;
    let has =
        |hd: &exr::meta::header::Header, n: &str| hd.channels.list.iter().any(|c| c.name.eq(n));
    let Some(layer) = meta
        .headers
        .iter()
        .position(|hd| has(hd, "R") && has(hd, "G") && has(hd, "B"))
    else {
        let names: Vec<String> = meta
            .headers
            .iter()
            .flat_map(|hd| hd.channels.list.iter().map(|c| c.name.to_string()))
            .collect();
        return Err(DecodeError::NoRgbLayer(names.join(", ")));
    };
    for hd in &meta.headers {
        if hd.deep {
            return Err(DecodeError::DeepData);
        }
        check_size(hd.layer_size.0, hd.layer_size.1, limits)?;
    }
    if limits.threads <= 1 {
        decode_exr_sequential(bytes, layer)
    } else {
        decode_exr_blocks(bytes, limits, layer)
    }
}

/// One thread: `exr`'s own flat reader with `.non_parallel()`, whole channels at once.
fn decode_exr_sequential(bytes: &[u8], layer_index: usize) -> Result<DecodedImage, DecodeError> {
    use exr::prelude::*;
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .all_layers()
        .all_attributes()
        .non_parallel()
        .from_buffered(Cursor::new(bytes))
        .map_err(|e| DecodeError::Exr(e.to_string()))?;
    let layer = image
        .layer_data
        .into_iter()
        .nth(layer_index)
        .ok_or_else(|| DecodeError::Exr("RGB layer missing after decoding".into()))?;
    let (w, h) = (layer.size.0, layer.size.1);
    let mut planes: [Option<Vec<f32>>; 3] = [None, None, None];
    for ch in layer.channel_data.list {
        let slot = match ch.name.to_string().as_str() {
            "R" => 0,
            "G" => 1,
            "B" => 2,
            _ => continue,
        };
        if ch.sampling != Vec2(1, 1) {
            return Err(DecodeError::Exr(format!(
                "channel {} is subsampled {:?}",
                ch.name, ch.sampling
            )));
        }
        let v = match ch.sample_data {
            FlatSamples::F32(v) => v,
            FlatSamples::F16(v) => {
                let mut out = vec![0f32; v.len()];
                half::slice::HalfFloatSliceExt::convert_to_f32_slice(v.as_slice(), &mut out);
                out
            }
            FlatSamples::U32(v) => v.into_iter().map(|u| u as f32).collect(),
        };
        if v.len() != w * h {
            return Err(DecodeError::Exr(format!(
                "channel {} has {} samples, expected {}",
                ch.name,
                v.len(),
                w * h
            )));
        }
        planes[slot] = Some(v);
    }
    let [Some(r), Some(g), Some(b)] = planes else {
        return Err(DecodeError::NoRgbLayer(
            "R, G or B missing after decoding".into(),
        ));
    };
    Ok(DecodedImage {
        format: CaptureFormat::Exr,
        width: w,
        height: h,
        pixels: Pixels::Planar([r, g, b]),
    })
}

/// Several threads: read the chunks, decompress them on our own scoped threads.
fn decode_exr_blocks(
    bytes: &[u8],
    limits: &DecodeLimits,
    layer: usize,
) -> Result<DecodedImage, DecodeError> {
    use exr::block::reader::Reader;
    let exr_err = |e: exr::error::Error| DecodeError::Exr(e.to_string());
    let reader = Reader::read_from_buffered(Cursor::new(bytes), false).map_err(exr_err)?;
    let meta = reader.meta_data().clone();
    let header = meta
        .headers
        .get(layer)
        .ok_or_else(|| DecodeError::Exr("RGB layer missing".into()))?;
    let (w, h) = (header.layer_size.0, header.layer_size.1);
    // channel index in the header → R/G/B slot
    let mut slot_of = Vec::with_capacity(header.channels.list.len());
    for ch in &header.channels.list {
        let slot = match ch.name.to_string().as_str() {
            "R" => Some(0),
            "G" => Some(1),
            "B" => Some(2),
            _ => None,
        };
        if slot.is_some() && ch.sampling != exr::math::Vec2(1, 1) {
            return Err(DecodeError::Exr(format!(
                "channel {} is subsampled {:?}",
                ch.name, ch.sampling
            )));
        }
        slot_of.push((slot, ch.sample_type));
    }

    // Read the compressed chunks of the RGB layer's full-resolution level (cheap, sequential).
    let chunks: Vec<exr::block::chunk::Chunk> = reader
        .filter_chunks(false, |_, _, block| {
            block.layer == layer && block.level == exr::math::Vec2(0, 0)
        })
        .map_err(exr_err)?
        .collect::<Result<_, _>>()
        .map_err(exr_err)?;

    // Decompress and convert on `threads` scoped threads of our own (never exr's thread pool),
    // each under catch_unwind, so a malformed chunk is an error, not an abort.
    let threads = limits.threads.clamp(1, 16).min(chunks.len().max(1));
    let per = chunks.len().div_ceil(threads);
    let mut groups: Vec<Vec<exr::block::chunk::Chunk>> = Vec::with_capacity(threads);
    let mut it = chunks.into_iter();
    for _ in 0..threads {
        groups.push(it.by_ref().take(per).collect());
    }
    let work = |group: Vec<exr::block::chunk::Chunk>| -> Result<Vec<Segment>, DecodeError> {
        let mut out = Vec::new();
        for chunk in group {
            let block = exr::block::UncompressedBlock::decompress_chunk(chunk, &meta, false)
                .map_err(exr_err)?;
            for line in block.lines(&header.channels) {
                let loc = line.location;
                let Some(&(Some(slot), sample_type)) = slot_of.get(loc.channel) else {
                    continue;
                };
                let (x, y, n) = (loc.position.0, loc.position.1, loc.sample_count);
                if x + n > w || y >= h {
                    return Err(DecodeError::Exr(format!(
                        "block line at ({x}, {y}) + {n} outside {w}×{h}"
                    )));
                }
                let v = line_to_f32(line.value, n, sample_type)?;
                out.push((slot, y * w + x, v));
            }
        }
        Ok(out)
    };
    let results: Vec<Result<Vec<Segment>, DecodeError>> = std::thread::scope(|scope| {
        let handles: Vec<_> = groups
            .into_iter()
            .map(|g| {
                scope.spawn(|| {
                    catch_unwind(AssertUnwindSafe(|| work(g)))
                        .unwrap_or_else(|p| Err(DecodeError::Panicked(panic_message(p))))
                })
            })
            .collect();
        handles
            .into_iter()
            .map(|hd| {
                hd.join()
                    .unwrap_or_else(|p| Err(DecodeError::Panicked(panic_message(p))))
            })
            .collect()
    });
    // Place the segments in memory order: every sample exactly once, no gap, no overlap.
    let mut segments: Vec<Segment> = Vec::new();
    for r in results {
        segments.extend(r?);
    }
    segments.sort_unstable_by_key(|(slot, start, _)| (*slot, *start));
    let mut planes: [Vec<f32>; 3] = [
        Vec::with_capacity(w * h),
        Vec::with_capacity(w * h),
        Vec::with_capacity(w * h),
    ];
    for (slot, start, v) in segments {
        let plane = &mut planes[slot];
        if start != plane.len() {
            return Err(DecodeError::Exr(format!(
                "chunks overlap or leave a gap in channel {} at sample {start}",
                ["R", "G", "B"][slot]
            )));
        }
        plane.extend_from_slice(&v);
    }
    if planes.iter().any(|p| p.len() != w * h) {
        return Err(DecodeError::Exr(format!(
            "incomplete image: R/G/B samples {:?} of {} (missing chunks)",
            planes.iter().map(Vec::len).collect::<Vec<_>>(),
            w * h
        )));
    }
    let [r, g, b] = planes;
    Ok(DecodedImage {
        format: CaptureFormat::Exr,
        width: w,
        height: h,
        pixels: Pixels::Planar([r, g, b]),
    })
}
