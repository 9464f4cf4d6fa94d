//! Shell: decoding one HDR capture (Radiance `.hdr` via `image`, OpenEXR via `exr`) from its
//! bytes into an interleaved linear RGB f32 buffer for the measurement core.
//!
//! Hardening, because one bad file must never stop a 13-hour run:
//! - the format is sniffed from the magic bytes, not trusted from the name;
//! - image dimensions are checked against [`DecodeLimits`] before any pixel buffer is allocated
//!   (EXR: from the header; Radiance: `image::Limits` on a `BufReader`);
//! - memory is bounded by [`DecodeLimits::max_bytes`]: before any pixel buffer is allocated, an
//!   upper bound of everything the decode will allocate is computed from the header (channels,
//!   pixels, stored sample sizes, block size, file length) and a file that needs more is refused
//!   with [`DecodeError::OverBudget`]. [`required_bytes`] gives that figure;
//! - OpenEXR: only the R, G and B channels of the first layer that has all three are
//!   materialised. The other channels and layers are never kept: their samples exist only inside
//!   one decompressed block at a time (which is why the block size, over all channels of the
//!   layer, is part of the budget);
//! - `exr`'s own parallel decoder (whose thread pool can abort the process on a malformed file)
//!   is never used. With one thread (`DecodeLimits::threads`, the default, for a worker pool
//!   that decodes several captures at once) the chunks are read and decompressed one at a time
//!   on the calling thread; with more, they are decompressed on our own scoped threads, each
//!   under `catch_unwind`. The whole decoder call runs under `catch_unwind` too, so a decoder
//!   panic becomes [`DecodeError::Panicked`].
//!   A file with missing, duplicated or overlapping chunks is an error, not a half-black image.

use crate::measure::averaging::{Layout, RgbView};
use std::io::{BufReader, Cursor};
use std::panic::{catch_unwind, AssertUnwindSafe};
use thiserror::Error;

#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum CaptureFormat {
    Hdr,
    Exr,
    /// 8- or 16-bit PNG, sRGB-encoded: linearised on decode.
    Png,
    /// 8-bit JPEG, sRGB-encoded: linearised on decode.
    Jpeg,
}

impl CaptureFormat {
    /// Low dynamic range: values are display-encoded codes in [0, 1] after linearising, and a
    /// code at its maximum is a clipped pixel.
    pub(crate) fn is_ldr(self) -> bool {
        matches!(self, CaptureFormat::Png | CaptureFormat::Jpeg)
    }
}

#[derive(Debug, Error, PartialEq)]
pub enum DecodeError {
    #[error("file is empty")]
    Empty,
    #[error("not a Radiance .hdr, OpenEXR, PNG or JPEG file (magic bytes {0:02x?})")]
    UnknownFormat(Vec<u8>),
    #[error("{format} decoder: {message}")]
    Ldr {
        format: &'static str,
        message: String,
    },
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
    /// The header implies a decode that needs more memory than [`DecodeLimits::max_bytes`].
    #[error(
        "decoding needs {needed} bytes, over the budget of {budget} bytes \
         (DecodeLimits::max_bytes): {pixels} pixels, {channels} channels \
         ({bytes_per_pixel} stored bytes per pixel), {block_bytes} bytes per decompressed block, \
         {header_bytes} header bytes"
    )]
    OverBudget {
        /// Upper bound of what the decode would allocate, in bytes.
        needed: u64,
        /// [`DecodeLimits::max_bytes`].
        budget: u64,
        /// Channels in the decoded layer (all of them: each block is decompressed whole).
        channels: usize,
        /// Pixels of the decoded layer.
        pixels: u64,
        /// Stored bytes per pixel over all channels of the layer (EXR: 2 per half, 4 per float
        /// or uint; Radiance: 4 for RGBE).
        bytes_per_pixel: u64,
        /// Bytes of the largest decompressed block (EXR: a chunk's lines or tile over all
        /// channels; Radiance: one scanline).
        block_bytes: u64,
        /// Length of the file's header(s). A header too large to parse within the budget is
        /// refused before it is parsed; the figures above are then 0 (not yet known).
        header_bytes: u64,
    },
}

/// Bounds on what a decoder may allocate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DecodeLimits {
    pub max_pixels: usize,
    pub max_dimension: u32,
    /// Threads for OpenEXR block decompression (our own scoped threads, not exr's pool).
    /// 1 inside a worker pool that already decodes several captures at once.
    pub threads: usize,
    /// Memory budget of one `decode` call, in bytes: an upper bound of everything the decoder
    /// allocates (output planes, decompressed blocks and decompressor scratch, copies of the
    /// compressed chunks, parsed headers), not counting the input bytes the caller holds.
    /// The bound is computed from the header before any pixel buffer is allocated (see
    /// [`required_bytes`]); a file that needs more is refused with [`DecodeError::OverBudget`].
    /// Each worker that decodes at the same time needs its own budget.
    /// Default 1 GiB: on one thread, a capture of up to `max_pixels` (64 MP: 768 MiB of f32
    /// planes) with any of the usual compressions; with several threads the compressed chunks
    /// and the decoded lines are held as well (16 bytes a pixel plus the file), about 35 MP.
    pub max_bytes: u64,
}

impl Default for DecodeLimits {
    fn default() -> Self {
        // 64 MP is 20× a UBO capture; 768 MiB of f32 RGB at most.
        DecodeLimits {
            max_pixels: 64 << 20,
            max_dimension: 32768,
            threads: 1,
            max_bytes: 1 << 30,
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
pub(crate) fn detect_format(bytes: &[u8]) -> Result<CaptureFormat, DecodeError> {
    if bytes.is_empty() {
        return Err(DecodeError::Empty);
    }
    if bytes.starts_with(&[0x76, 0x2f, 0x31, 0x01]) {
        return Ok(CaptureFormat::Exr);
    }
    if bytes.starts_with(b"#?") {
        return Ok(CaptureFormat::Hdr);
    }
    if bytes.starts_with(&[0x89, b'P', b'N', b'G', 0x0d, 0x0a, 0x1a, 0x0a]) {
        return Ok(CaptureFormat::Png);
    }
    if bytes.starts_with(&[0xff, 0xd8, 0xff]) {
        return Ok(CaptureFormat::Jpeg);
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

/// Decode a capture from its bytes. Never panics. Allocates at most what [`required_bytes`]
/// reports for the same input and limits, and refuses input for which that exceeds
/// [`DecodeLimits::max_bytes`] before allocating any pixel buffer.
pub fn decode(bytes: &[u8], limits: &DecodeLimits) -> Result<DecodedImage, DecodeError> {
    let format = detect_format(bytes)?;
    let result = catch_unwind(AssertUnwindSafe(|| match format {
        CaptureFormat::Hdr => decode_hdr(bytes, limits),
        CaptureFormat::Exr => decode_exr(bytes, limits),
        CaptureFormat::Png | CaptureFormat::Jpeg => decode_ldr(bytes, format, limits),
    }));
    match result {
        Ok(r) => r,
        Err(p) => Err(DecodeError::Panicked(panic_message(p))),
    }
}

/// The upper bound of what [`decode`] allocates for this input under these limits (the figure
/// checked against [`DecodeLimits::max_bytes`]), computed from the header alone. When the
/// header itself is too large to parse within the budget, the cost of parsing it (what
/// `decode` refuses before parsing). The same errors as `decode` for a header that is
/// unreadable, too large or has no RGB layer; never [`DecodeError::OverBudget`]. Never panics.
pub fn required_bytes(bytes: &[u8], limits: &DecodeLimits) -> Result<u64, DecodeError> {
    let format = detect_format(bytes)?;
    let result = catch_unwind(AssertUnwindSafe(|| match format {
        CaptureFormat::Hdr => {
            let header = hdr_header_size(bytes);
            let cost = Cost::of_header(header);
            if cost.check(limits).is_err() {
                return Ok(cost.needed);
            }
            let dec = hdr_decoder(bytes)?;
            hdr_cost(&dec, header, limits).map(|c| c.needed)
        }
        CaptureFormat::Exr => {
            let header = exr_header_size(bytes);
            let cost = Cost::of_header(header);
            if cost.check(limits).is_err() {
                return Ok(cost.needed);
            }
            let reader = exr_reader(bytes)?;
            exr_plan(reader.meta_data(), header, bytes.len(), limits).map(|(_, c)| c.needed)
        }
        CaptureFormat::Png | CaptureFormat::Jpeg => {
            let dec = ldr_decoder(bytes, format)?;
            let (w, h) = dec.dimensions();
            check_size(w as usize, h as usize, limits)?;
            Ok(ldr_cost(w, h, dec.total_bytes()))
        }
    }));
    match result {
        Ok(r) => r,
        Err(p) => Err(DecodeError::Panicked(panic_message(p))),
    }
}

/// An upper bound of a decode's allocations, with the header figures it was computed from.
#[derive(Debug, Clone, Copy)]
struct Cost {
    needed: u64,
    channels: usize,
    pixels: u64,
    bytes_per_pixel: u64,
    block_bytes: u64,
    header_bytes: u64,
}

impl Cost {
    fn check(self, limits: &DecodeLimits) -> Result<(), DecodeError> {
        if self.needed <= limits.max_bytes {
            return Ok(());
        }
        Err(DecodeError::OverBudget {
            needed: self.needed,
            budget: limits.max_bytes,
            channels: self.channels,
            pixels: self.pixels,
            bytes_per_pixel: self.bytes_per_pixel,
            block_bytes: self.block_bytes,
            header_bytes: self.header_bytes,
        })
    }

    /// What parsing a header costs, before anything else is known about it.
    fn of_header(header: HeaderSize) -> Cost {
        let header_bytes = header.bytes as u64;
        Cost {
            needed: FIXED_OVERHEAD
                .saturating_add(header_bytes.saturating_mul(PER_HEADER_BYTE))
                .saturating_add((header.items as u64).saturating_mul(header.per_item)),
            channels: 0,
            pixels: 0,
            bytes_per_pixel: 0,
            block_bytes: 0,
            header_bytes,
        }
    }
}

/// Allocations that do not scale with the image: decoder tables (PIZ Huffman and bitmap, DWA
/// and B44 lookup tables), buffered readers, small per-call vectors.
const FIXED_OVERHEAD: u64 = 4 << 20;

/// The size of a file's header(s) on disk, found by scanning their framing without parsing.
#[derive(Debug, Clone, Copy)]
struct HeaderSize {
    /// Bytes of the header(s).
    bytes: usize,
    /// Attributes and headers (OpenEXR) or lines (Radiance).
    items: usize,
    /// What the parser keeps per item, in bytes.
    per_item: u64,
}

/// Parsed headers per header byte on disk: attribute values and channel lists (an 18-byte
/// channel entry becomes a 56-byte description), in vectors that grow by doubling.
const PER_HEADER_BYTE: u64 = 8;

/// Parsed OpenEXR header per attribute, whatever its length: an attribute of 10 bytes becomes
/// an entry of about 400 bytes in a hash map, which holds its old and new tables while it
/// grows (up to 3.4 entries' worth per attribute).
const PER_EXR_ATTRIBUTE: u64 = 2048;

/// Parsed Radiance header per line, whatever its length: a line of 2 bytes becomes a pair of
/// strings (48 bytes) in a vector that grows by doubling.
const PER_HDR_LINE: u64 = 128;

/// OpenEXR bookkeeping per chunk: the offset table entry (read into a vector that grows by
/// doubling), the filtered offset, the set of blocks seen, and in the threaded path the chunk's
/// descriptor, twice while the chunks are split among the threads.
const PER_CHUNK: u64 = 256;

/// Blocks alive at once while one chunk is decompressed: the compressed copy (which `exr` caps
/// at one block's uncompressed size), the decompressed block, and the decompressor's scratch
/// (B44 and PIZ build one more block-sized buffer; ZIP's byte interleaving keeps a block-sized
/// thread-local buffer).
const BLOCK_COPIES: u64 = 4;

/// The same for DWA, counted in blocks padded to whole 8×8 DCT tiles: besides the compressed
/// copy and the output, the inflated sections (the RLE one up to twice its unpacked size, see
/// [`check_dwa_counters`]), the unpacked RLE planes, and the decoded DCT coefficients.
const DWA_BLOCK_COPIES: u64 = 8;

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

/// A Radiance file's header: up to and including the resolution line that follows the first
/// empty line, or the whole file when there is no empty line (the decoder then reads all of it
/// looking for one), and its lines.
fn hdr_header_size(bytes: &[u8]) -> HeaderSize {
    let end = match bytes.windows(2).position(|w| w == b"\n\n") {
        None => bytes.len(),
        Some(blank) => {
            let resolution = blank + 2;
            match bytes
                .get(resolution..)
                .and_then(|r| r.iter().position(|&b| b == b'\n'))
            {
                Some(n) => resolution + n + 1,
                None => bytes.len(),
            }
        }
    };
    let header = bytes.get(..end).unwrap_or(bytes);
    HeaderSize {
        bytes: end,
        items: header.iter().filter(|&&b| b == b'\n').count() + 1,
        per_item: PER_HDR_LINE,
    }
}

type HdrDecoder<'a> = image::codecs::hdr::HdrDecoder<BufReader<Cursor<&'a [u8]>>>;

fn hdr_decoder(bytes: &[u8]) -> Result<HdrDecoder<'_>, DecodeError> {
    HdrDecoder::new(BufReader::new(Cursor::new(bytes))).map_err(|e| DecodeError::Hdr(e.to_string()))
}

/// The parsed header (kept by the decoder), the f32 RGB output (12 bytes a pixel) and one RGBE
/// scanline.
fn hdr_cost(
    dec: &HdrDecoder<'_>,
    header: HeaderSize,
    limits: &DecodeLimits,
) -> Result<Cost, DecodeError> {
    use image::ImageDecoder;
    let (w, h) = dec.dimensions();
    check_size(w as usize, h as usize, limits)?;
    let pixels = u64::from(w).saturating_mul(u64::from(h));
    let scanline = u64::from(w).saturating_mul(4);
    let header = Cost::of_header(header);
    Ok(Cost {
        needed: header
            .needed
            .saturating_add(pixels.saturating_mul(12))
            .saturating_add(scanline),
        channels: 3,
        pixels,
        bytes_per_pixel: 4,
        block_bytes: scanline,
        header_bytes: header.header_bytes,
    })
}

fn decode_hdr(bytes: &[u8], limits: &DecodeLimits) -> Result<DecodedImage, DecodeError> {
    use image::ImageDecoder;
    // the header parser keeps every line: bound it before it runs
    let header = hdr_header_size(bytes);
    Cost::of_header(header).check(limits)?;
    let mut dec = hdr_decoder(bytes)?;
    let (w, h) = dec.dimensions();
    hdr_cost(&dec, header, limits)?.check(limits)?;
    let mut lim = image::Limits::default();
    lim.max_image_width = Some(limits.max_dimension);
    lim.max_image_height = Some(limits.max_dimension);
    lim.max_alloc = Some(
        (limits.max_pixels as u64)
            .saturating_mul(12)
            .saturating_add(1 << 20)
            .min(limits.max_bytes),
    );
    dec.set_limits(lim)
        .map_err(|e| DecodeError::Hdr(e.to_string()))?;
    // w × h ≤ max_pixels (checked above), so this cannot overflow
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

/// A PNG or JPEG decoder over `bytes` (the `image` crate's, on a `BufReader`).
fn ldr_decoder(
    bytes: &[u8],
    format: CaptureFormat,
) -> Result<Box<dyn image::ImageDecoder + '_>, DecodeError> {
    let reader = BufReader::new(Cursor::new(bytes));
    let (name, dec): (&'static str, Result<Box<dyn image::ImageDecoder>, _>) = match format {
        CaptureFormat::Png => (
            "PNG",
            image::codecs::png::PngDecoder::new(reader)
                .map(|d| Box::new(d) as Box<dyn image::ImageDecoder>),
        ),
        _ => (
            "JPEG",
            image::codecs::jpeg::JpegDecoder::new(reader)
                .map(|d| Box::new(d) as Box<dyn image::ImageDecoder>),
        ),
    };
    dec.map_err(|e| DecodeError::Ldr {
        format: name,
        message: e.to_string(),
    })
}

/// An upper bound of what an LDR decode allocates: the f32 RGB result, the decoder's output
/// buffer, as much again for its own planes (JPEG components, interlaced PNG passes), and 1 MiB
/// of fixed working set (zlib window, rows, Huffman tables, the 16-bit sRGB table).
fn ldr_cost(w: u32, h: u32, decoded_bytes: u64) -> u64 {
    (w as u64)
        .saturating_mul(h as u64)
        .saturating_mul(12)
        .saturating_add(decoded_bytes.saturating_mul(2))
        .saturating_add(1 << 20)
}

/// Linear values of the 256 8-bit sRGB codes.
fn srgb_table_8() -> &'static [f32] {
    static T: std::sync::OnceLock<Vec<f32>> = std::sync::OnceLock::new();
    T.get_or_init(|| {
        (0..=255u32)
            .map(|c| srgb_to_linear(c as f32 / 255.0))
            .collect()
    })
}

/// Linear values of the 65,536 16-bit sRGB codes.
fn srgb_table_16() -> &'static [f32] {
    static T: std::sync::OnceLock<Vec<f32>> = std::sync::OnceLock::new();
    T.get_or_init(|| {
        (0..=65535u32)
            .map(|c| srgb_to_linear(c as f32 / 65535.0))
            .collect()
    })
}

/// The sRGB transfer function undone: code value in [0, 1] → linear.
fn srgb_to_linear(v: f32) -> f32 {
    if v <= 0.04045 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

/// Decode a PNG or JPEG capture to linear RGB: the sRGB transfer function is undone (through a
/// table for each code value), grey becomes R = G = B, alpha is dropped. A saturated code reads
/// exactly 1.0, so the averaging counts it as clipped at a clip level of 1.
fn decode_ldr(
    bytes: &[u8],
    format: CaptureFormat,
    limits: &DecodeLimits,
) -> Result<DecodedImage, DecodeError> {
    use image::{ColorType, ImageDecoder};
    let name = if format == CaptureFormat::Png {
        "PNG"
    } else {
        "JPEG"
    };
    let err = |e: image::ImageError| DecodeError::Ldr {
        format: name,
        message: e.to_string(),
    };
    let mut dec = ldr_decoder(bytes, format)?;
    let (w, h) = dec.dimensions();
    check_size(w as usize, h as usize, limits)?;
    let needed = ldr_cost(w, h, dec.total_bytes());
    if needed > limits.max_bytes {
        return Err(DecodeError::OverBudget {
            needed,
            budget: limits.max_bytes,
            channels: dec.color_type().channel_count() as usize,
            pixels: w as u64 * h as u64,
            bytes_per_pixel: dec.color_type().bytes_per_pixel() as u64,
            block_bytes: dec.total_bytes(),
            header_bytes: 0,
        });
    }
    let mut lim = image::Limits::default();
    lim.max_image_width = Some(limits.max_dimension);
    lim.max_image_height = Some(limits.max_dimension);
    lim.max_alloc = Some(limits.max_bytes);
    dec.set_limits(lim).map_err(err)?;
    let colour = dec.color_type();
    let channels = colour.channel_count() as usize;
    // w × h ≤ max_pixels (checked above)
    let n = (w as usize) * (h as usize);
    let mut raw = vec![0u8; dec.total_bytes() as usize];
    dec.read_image(&mut raw).map_err(err)?;
    let mut data = vec![0f32; n * 3];
    match colour {
        ColorType::L8 | ColorType::La8 | ColorType::Rgb8 | ColorType::Rgba8 => {
            let table = srgb_table_8();
            for (px, p) in data.chunks_exact_mut(3).zip(raw.chunks_exact(channels)) {
                if channels < 3 {
                    px.fill(table[p[0] as usize]);
                } else {
                    for k in 0..3 {
                        px[k] = table[p[k] as usize];
                    }
                }
            }
        }
        ColorType::L16 | ColorType::La16 | ColorType::Rgb16 | ColorType::Rgba16 => {
            let table = srgb_table_16();
            let code = |p: &[u8], k: usize| u16::from_ne_bytes([p[2 * k], p[2 * k + 1]]) as usize;
            for (px, p) in data.chunks_exact_mut(3).zip(raw.chunks_exact(2 * channels)) {
                if channels < 3 {
                    px.fill(table[code(p, 0)]);
                } else {
                    for k in 0..3 {
                        px[k] = table[code(p, k)];
                    }
                }
            }
        }
        other => {
            return Err(DecodeError::Ldr {
                format: name,
                message: format!("colour type {other:?} is not supported"),
            })
        }
    }
    Ok(DecodedImage {
        format,
        width: w as usize,
        height: h as usize,
        pixels: Pixels::Interleaved(data),
    })
}

/// Convert one line of native-endian samples (as `exr` leaves them in a decompressed block)
/// into `dst`. f16 goes through `half`'s slice conversion, which uses the CPU's F16C
/// instructions when it has them; f32 is a plain copy when the line is aligned.
fn convert_line(
    src: &[u8],
    dst: &mut [f32],
    sample_type: exr::meta::attribute::SampleType,
) -> Result<(), DecodeError> {
    use exr::meta::attribute::SampleType;
    use half::slice::{HalfBitsSliceExt, HalfFloatSliceExt};
    let size = match sample_type {
        SampleType::F16 => 2,
        SampleType::F32 | SampleType::U32 => 4,
    };
    if Some(src.len()) != dst.len().checked_mul(size) {
        return Err(DecodeError::Exr(format!(
            "line has {} bytes, expected {} samples of {size} bytes",
            src.len(),
            dst.len()
        )));
    }
    match sample_type {
        SampleType::F16 => match bytemuck::try_cast_slice::<u8, u16>(src) {
            Ok(bits) => bits
                .reinterpret_cast::<half::f16>()
                .convert_to_f32_slice(dst),
            Err(_) => {
                for (d, c) in dst.iter_mut().zip(src.chunks_exact(2)) {
                    *d = half::f16::from_bits(u16::from_ne_bytes([c[0], c[1]])).to_f32();
                }
            }
        },
        SampleType::F32 => match bytemuck::try_cast_slice::<u8, f32>(src) {
            Ok(v) => dst.copy_from_slice(v),
            Err(_) => {
                for (d, c) in dst.iter_mut().zip(src.chunks_exact(4)) {
                    *d = f32::from_ne_bytes([c[0], c[1], c[2], c[3]]);
                }
            }
        },
        SampleType::U32 => {
            for (d, c) in dst.iter_mut().zip(src.chunks_exact(4)) {
                *d = u32::from_ne_bytes([c[0], c[1], c[2], c[3]]) as f32;
            }
        }
    }
    Ok(())
}

fn exr_err(e: exr::error::Error) -> DecodeError {
    DecodeError::Exr(e.to_string())
}

type ExrReader<'a> = exr::block::reader::Reader<Cursor<&'a [u8]>>;

fn exr_reader(bytes: &[u8]) -> Result<ExrReader<'_>, DecodeError> {
    exr::block::reader::Reader::read_from_buffered(Cursor::new(bytes), false).map_err(exr_err)
}

/// An OpenEXR file's magic number, version and header(s) on disk, from the attribute framing
/// alone (name and type as NUL-terminated strings, an i32 size, the value), without reading
/// any value: what the header parser will read. Where the framing breaks (the parser fails
/// there), the whole file and the attributes seen so far.
fn exr_header_size(bytes: &[u8]) -> HeaderSize {
    let multipart = bytes
        .get(4..8)
        .and_then(|v| v.try_into().ok())
        .is_some_and(|v| u32::from_le_bytes(v) & 0x1000 != 0);
    let mut items = 1usize;
    let broken = |items| HeaderSize {
        bytes: bytes.len(),
        items,
        per_item: PER_EXR_ATTRIBUTE,
    };
    let nul_terminated = |pos: usize| -> Option<usize> {
        let len = bytes.get(pos..)?.iter().position(|&b| b == 0)?;
        Some(pos + len + 1)
    };
    let mut pos = 8usize;
    loop {
        // one header: attributes up to an empty name
        loop {
            let Some(after_name) = nul_terminated(pos) else {
                return broken(items);
            };
            if after_name == pos + 1 {
                pos = after_name;
                break;
            }
            items += 1;
            let Some(after_type) = nul_terminated(after_name) else {
                return broken(items);
            };
            let size = bytes
                .get(after_type..after_type + 4)
                .and_then(|v| v.try_into().ok())
                .map(i32::from_le_bytes)
                .and_then(|v| usize::try_from(v).ok());
            match size.and_then(|n| (after_type + 4).checked_add(n)) {
                Some(end) if end <= bytes.len() => pos = end,
                _ => return broken(items),
            }
        }
        if !multipart {
            return HeaderSize {
                bytes: pos,
                items,
                per_item: PER_EXR_ATTRIBUTE,
            };
        }
        // the list of headers of a multi-part file ends with an empty header
        match bytes.get(pos) {
            Some(0) => {
                return HeaderSize {
                    bytes: pos + 1,
                    items,
                    per_item: PER_EXR_ATTRIBUTE,
                }
            }
            Some(_) => items += 1,
            None => return broken(items),
        }
    }
}

/// Threads the block path uses at most (`DecodeLimits::threads` is clamped to this).
const MAX_THREADS: usize = 16;

/// Bookkeeping per R, G or B line in the threaded path: the segment's entry in the workers'
/// vectors (which grow by doubling) and in the merged, sorted vector.
const PER_SEGMENT: u64 = 128;

fn sample_bytes(sample_type: exr::meta::attribute::SampleType) -> u64 {
    use exr::meta::attribute::SampleType;
    match sample_type {
        SampleType::F16 => 2,
        SampleType::F32 | SampleType::U32 => 4,
    }
}

/// Find the layer to decode (the first with R, G and B), check every header's size, and bound
/// what decoding that layer allocates (see [`Cost`] and the constants above it):
/// - one thread: the parsed headers, per-chunk bookkeeping, the three f32 planes (12 bytes a
///   pixel), and [`BLOCK_COPIES`] blocks of the layer (all its channels) while one chunk is
///   decompressed; in a multi-part file also the largest block of any part, once;
/// - several threads: the same, plus the compressed chunks of the layer (at most the file, as
///   `decode_exr_blocks` checks), the decoded R, G, B lines before they are placed (12 bytes a
///   pixel, merged one plane at a time, so 16 bytes a pixel in all) and their bookkeeping, and
///   one set of block copies per thread.
fn exr_plan(
    meta: &exr::meta::MetaData,
    header_size: HeaderSize,
    file_len: usize,
    limits: &DecodeLimits,
) -> Result<(usize, Cost), DecodeError> {
    use exr::meta::BlockDescription;
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
    let header = &meta.headers[layer];
    let (w, h) = (header.layer_size.0 as u64, header.layer_size.1 as u64);
    let pixels = w.saturating_mul(h);
    let bytes_per_pixel = header.channels.list.iter().fold(0u64, |sum, c| {
        sum.saturating_add(sample_bytes(c.sample_type))
    });
    // `exr` sizes the compressed buffer of a chunk by the declared block size (a tile may be
    // declared larger than the layer) and the decompressed block by the same or less
    let (block_w, block_h) = match header.blocks {
        BlockDescription::ScanLines => (w, header.compression.scan_lines_per_block() as u64),
        BlockDescription::Tiles(t) => (t.tile_size.0 as u64, t.tile_size.1 as u64),
    };
    let dwa = is_dwa(header.compression);
    let (pad_w, pad_h) = if dwa {
        (padded_to_dct(block_w), padded_to_dct(block_h))
    } else {
        (block_w, block_h)
    };
    let block_bytes = bytes_per_pixel.saturating_mul(pad_w).saturating_mul(pad_h);
    let copies = if dwa { DWA_BLOCK_COPIES } else { BLOCK_COPIES };
    // In a multi-part file a chunk names its own part, and `exr` allocates its compressed data
    // (up to that part's declared block size) before the part is checked: the largest block of
    // any part can be allocated once while the chunks are read.
    let any_part_block = if meta.headers.len() > 1 {
        meta.headers
            .iter()
            .map(|hd| {
                let area = match hd.blocks {
                    BlockDescription::ScanLines => (hd.layer_size.0 as u64)
                        .saturating_mul(hd.compression.scan_lines_per_block() as u64),
                    BlockDescription::Tiles(t) => {
                        (t.tile_size.0 as u64).saturating_mul(t.tile_size.1 as u64)
                    }
                };
                (hd.channels.bytes_per_pixel as u64).saturating_mul(area)
            })
            .max()
            .unwrap_or(0)
    } else {
        0
    };
    let chunks = meta
        .headers
        .iter()
        .fold(0u64, |sum, hd| sum.saturating_add(hd.chunk_count as u64))
        .min(file_len as u64 / 8 + 1);
    let threads = limits.threads.clamp(1, MAX_THREADS) as u64;
    let header_cost = Cost::of_header(header_size);
    let mut needed = header_cost
        .needed
        .saturating_add(any_part_block)
        .saturating_add(chunks.saturating_mul(PER_CHUNK))
        .saturating_add(pixels.saturating_mul(12))
        .saturating_add(block_bytes.saturating_mul(copies).saturating_mul(threads));
    if threads > 1 {
        let lines = h
            .saturating_mul(w.div_ceil(block_w.max(1)))
            .saturating_mul(3);
        needed = needed
            .saturating_add(file_len as u64)
            .saturating_add(pixels.saturating_mul(4))
            .saturating_add(lines.saturating_mul(PER_SEGMENT));
    }
    Ok((
        layer,
        Cost {
            needed,
            channels: header.channels.list.len(),
            pixels,
            bytes_per_pixel,
            block_bytes,
            header_bytes: header_cost.header_bytes,
        },
    ))
}

fn decode_exr(bytes: &[u8], limits: &DecodeLimits) -> Result<DecodedImage, DecodeError> {
    // the header parser keeps every attribute: bound it before it runs
    let header = exr_header_size(bytes);
    Cost::of_header(header).check(limits)?;
    let reader = exr_reader(bytes)?;
    let (layer, cost) = exr_plan(reader.meta_data(), header, bytes.len(), limits)?;
    cost.check(limits)?;
    if limits.threads <= 1 {
        decode_exr_sequential(reader, layer)
    } else {
        decode_exr_blocks(reader, limits, layer, bytes.len())
    }
}

/// For each channel of the header, its R/G/B slot (None for any other channel) and sample
/// type. R, G and B must not be subsampled.
fn rgb_slots(
    header: &exr::meta::header::Header,
) -> Result<Vec<(Option<usize>, exr::meta::attribute::SampleType)>, DecodeError> {
    header
        .channels
        .list
        .iter()
        .map(|ch| {
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
            Ok((slot, ch.sample_type))
        })
        .collect()
}

fn is_dwa(compression: exr::compression::Compression) -> bool {
    use exr::compression::Compression;
    matches!(compression, Compression::DWAA(_) | Compression::DWAB(_))
}

/// `n` rounded up to whole 8-pixel DCT tiles.
fn padded_to_dct(n: u64) -> u64 {
    n.div_ceil(8).saturating_mul(8)
}

/// Check a chunk before `exr` decompresses it: it must belong to the layer being decoded (the
/// chunk's own part number picks the header `exr` decompresses it with), and a DWA chunk's
/// counters must fit its block.
fn check_chunk(
    chunk: &exr::block::chunk::Chunk,
    layer: usize,
    header: &exr::meta::header::Header,
) -> Result<(), DecodeError> {
    use exr::block::chunk::CompressedBlock;
    if chunk.layer_index != layer {
        return Err(DecodeError::Exr(format!(
            "chunk of layer {} among the chunks of layer {layer}",
            chunk.layer_index
        )));
    }
    if !is_dwa(header.compression) {
        return Ok(());
    }
    let data = match &chunk.compressed_block {
        CompressedBlock::ScanLine(b) => &b.compressed_pixels_le,
        CompressedBlock::Tile(b) => &b.compressed_pixels_le,
        CompressedBlock::DeepScanLine(_) | CompressedBlock::DeepTile(_) => {
            return Err(DecodeError::DeepData)
        }
    };
    let tile = header
        .get_block_data_indices(&chunk.compressed_block)
        .map_err(exr_err)?;
    let rect = header
        .get_absolute_block_pixel_coordinates(tile)
        .map_err(exr_err)?;
    check_dwa_counters(
        data,
        header.channels.bytes_per_pixel as u64,
        rect.size.0 as u64,
        rect.size.1 as u64,
    )
}

/// A DWA chunk starts with eleven u64 counters, and `exr` sizes five buffers from them before
/// it reads any data: the raw ("unknown") section, the AC and DC coefficient arrays, and the
/// RLE section before and after unpacking. For a `w`×`h` block of `bytes_per_pixel`, the
/// unknown and RLE channels hold their samples and each lossy channel at most one 2-byte
/// coefficient per pixel of the block padded to 8×8 tiles, so together they fit the padded
/// block; the packed RLE section is at most twice its unpacked size (OpenEXR's encoder adds
/// one byte per 127). An empty chunk or one of exactly the block's size is stored raw and has
/// no counters.
fn check_dwa_counters(
    data: &[u8],
    bytes_per_pixel: u64,
    w: u64,
    h: u64,
) -> Result<(), DecodeError> {
    let block = bytes_per_pixel.saturating_mul(w).saturating_mul(h);
    if data.is_empty() || data.len() as u64 == block {
        return Ok(());
    }
    // shorter than the counters: `exr` reports the truncation
    let Some(leader) = data.get(..88) else {
        return Ok(());
    };
    let mut c = [0u64; 11];
    for (v, b) in c.iter_mut().zip(leader.chunks_exact(8)) {
        *v = u64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]]);
    }
    let [_, unknown, _, _, _, _, rle_packed, rle, ac, dc, _] = c;
    let padded = bytes_per_pixel
        .saturating_mul(padded_to_dct(w))
        .saturating_mul(padded_to_dct(h));
    let claimed = unknown
        .saturating_add(rle)
        .saturating_add(ac.saturating_mul(2))
        .saturating_add(dc.saturating_mul(2));
    if claimed > padded || rle_packed > rle.saturating_mul(2).saturating_add(64) {
        return Err(DecodeError::Exr(format!(
            "DWA chunk claims sections of {claimed} bytes (RLE {rle_packed} packed, {rle} \
             unpacked) for a {w}×{h} block of {padded} bytes"
        )));
    }
    Ok(())
}

/// A decompressed block must belong to the layer being decoded and to its full-resolution
/// level: the chunk's own part number and level can disagree with the offset table that led
/// to it.
fn check_block(block: &exr::block::UncompressedBlock, layer: usize) -> Result<(), DecodeError> {
    if block.index.layer != layer || block.index.level != exr::math::Vec2(0, 0) {
        return Err(DecodeError::Exr(format!(
            "chunk of layer {} level {:?} where layer {layer} level (0, 0) was expected",
            block.index.layer, block.index.level
        )));
    }
    Ok(())
}

/// Index of a line's first sample in a `w`×`h` plane, checked to lie inside it.
fn line_start(
    loc: &exr::block::lines::LineIndex,
    w: usize,
    h: usize,
) -> Result<usize, DecodeError> {
    let (x, y, n) = (loc.position.0, loc.position.1, loc.sample_count);
    match x.checked_add(n) {
        Some(end) if end <= w && y < h => Ok(y * w + x),
        _ => Err(DecodeError::Exr(format!(
            "block line at ({x}, {y}) + {n} outside {w}×{h}"
        ))),
    }
}

fn incomplete(filled: [usize; 3], n: usize) -> DecodeError {
    DecodeError::Exr(format!(
        "incomplete image: R/G/B samples {filled:?} of {n} (missing chunks)"
    ))
}

/// One thread: stream the layer's full-resolution chunks, decompress each, and convert its R,
/// G and B lines straight into the planes. Only one chunk and one decompressed block are alive
/// at a time. Every block may arrive once; with the lines checked to lie inside the image,
/// three full sample counts then mean every sample was written exactly once.
fn decode_exr_sequential(reader: ExrReader<'_>, layer: usize) -> Result<DecodedImage, DecodeError> {
    use exr::block::reader::ChunksReader;
    let header = reader
        .headers()
        .get(layer)
        .ok_or_else(|| DecodeError::Exr("RGB layer missing".into()))?;
    let (w, h) = (header.layer_size.0, header.layer_size.1);
    let slots = rgb_slots(header)?;
    // w × h ≤ max_pixels (checked in `exr_plan`), so this cannot overflow
    let n = w * h;
    let mut planes = [vec![0f32; n], vec![0f32; n], vec![0f32; n]];
    let mut filled = [0usize; 3];
    let mut seen = std::collections::HashSet::new();
    let mut chunks = reader
        .filter_chunks(false, |_, _, block| {
            block.layer == layer && block.level == exr::math::Vec2(0, 0)
        })
        .map_err(exr_err)?;
    while let Some(chunk) = chunks.next() {
        let chunk = chunk.map_err(exr_err)?;
        let meta = chunks.meta_data();
        check_chunk(&chunk, layer, &meta.headers[layer])?;
        let block =
            exr::block::UncompressedBlock::decompress_chunk(chunk, meta, false).map_err(exr_err)?;
        check_block(&block, layer)?;
        let position = (block.index.pixel_position.0, block.index.pixel_position.1);
        if !seen.insert(position) {
            return Err(DecodeError::Exr(format!(
                "two chunks hold the block at {position:?}"
            )));
        }
        let channels = &meta.headers[layer].channels;
        for line in block.lines(channels) {
            let Some(&(Some(slot), sample_type)) = slots.get(line.location.channel) else {
                continue;
            };
            let start = line_start(&line.location, w, h)?;
            let count = line.location.sample_count;
            // in bounds: `line_start` checked x + count ≤ w and y < h
            let dst = &mut planes[slot][start..start + count];
            convert_line(line.value, dst, sample_type)?;
            filled[slot] += count;
        }
    }
    if filled != [n; 3] {
        return Err(incomplete(filled, n));
    }
    let [r, g, b] = planes;
    Ok(DecodedImage {
        format: CaptureFormat::Exr,
        width: w,
        height: h,
        pixels: Pixels::Planar([r, g, b]),
    })
}

/// One decoded row segment of one channel: (channel slot 0..3, first sample index, samples).
type Segment = (usize, usize, Vec<f32>);

/// Several threads: read the layer's chunks (their total checked against the file length, so
/// chunks that overlap in the file cannot multiply it), decompress them on our own scoped
/// threads, then place the segments in order.
fn decode_exr_blocks(
    reader: ExrReader<'_>,
    limits: &DecodeLimits,
    layer: usize,
    file_len: usize,
) -> Result<DecodedImage, DecodeError> {
    use exr::block::chunk::{Chunk, CompressedBlock};
    use exr::block::reader::ChunksReader;
    let header = reader
        .headers()
        .get(layer)
        .ok_or_else(|| DecodeError::Exr("RGB layer missing".into()))?;
    let (w, h) = (header.layer_size.0, header.layer_size.1);
    let slots = rgb_slots(header)?;
    // w × h ≤ max_pixels (checked in `exr_plan`), so this cannot overflow
    let n = w * h;

    // Read the compressed chunks of the RGB layer's full-resolution level (cheap, sequential).
    let mut reader = reader
        .filter_chunks(false, |_, _, block| {
            block.layer == layer && block.level == exr::math::Vec2(0, 0)
        })
        .map_err(exr_err)?;
    let mut chunks: Vec<Chunk> = Vec::with_capacity(reader.len());
    let mut compressed = 0usize;
    while let Some(chunk) = reader.next() {
        let chunk = chunk.map_err(exr_err)?;
        compressed = compressed.saturating_add(match &chunk.compressed_block {
            CompressedBlock::ScanLine(b) => b.compressed_pixels_le.len(),
            CompressedBlock::Tile(b) => b.compressed_pixels_le.len(),
            CompressedBlock::DeepScanLine(_) | CompressedBlock::DeepTile(_) => {
                return Err(DecodeError::DeepData)
            }
        });
        if compressed > file_len {
            return Err(DecodeError::Exr(format!(
                "chunks overlap: {compressed} bytes of chunks in a {file_len}-byte file"
            )));
        }
        check_chunk(&chunk, layer, &reader.meta_data().headers[layer])?;
        chunks.push(chunk);
    }
    let meta = reader.meta_data();
    let header = &meta.headers[layer];

    // Decompress and convert on `threads` scoped threads of our own (never exr's thread pool),
    // each under catch_unwind, so a malformed chunk is an error, not an abort.
    let threads = limits
        .threads
        .clamp(1, MAX_THREADS)
        .min(chunks.len().max(1));
    let per = chunks.len().div_ceil(threads);
    let mut groups: Vec<Vec<Chunk>> = Vec::with_capacity(threads);
    let mut it = chunks.into_iter();
    for _ in 0..threads {
        groups.push(it.by_ref().take(per).collect());
    }
    drop(it);
    let work = |group: Vec<Chunk>| -> Result<Vec<Segment>, DecodeError> {
        let mut out = Vec::new();
        for chunk in group {
            let block = exr::block::UncompressedBlock::decompress_chunk(chunk, meta, false)
                .map_err(exr_err)?;
            check_block(&block, layer)?;
            for line in block.lines(&header.channels) {
                let Some(&(Some(slot), sample_type)) = slots.get(line.location.channel) else {
                    continue;
                };
                let start = line_start(&line.location, w, h)?;
                let mut v = vec![0f32; line.location.sample_count];
                convert_line(line.value, &mut v, sample_type)?;
                out.push((slot, start, v));
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
    // Place the segments in memory order: every sample exactly once, no gap, no overlap. Each
    // plane is allocated when its first segment comes and each segment freed once copied, so
    // the segments and the planes together never exceed 16 bytes a pixel.
    let mut parts = Vec::with_capacity(results.len());
    for r in results {
        parts.push(r?);
    }
    let mut segments: Vec<Segment> = Vec::with_capacity(parts.iter().map(Vec::len).sum());
    for p in parts {
        segments.extend(p);
    }
    segments.sort_unstable_by_key(|(slot, start, _)| (*slot, *start));
    let mut planes: [Vec<f32>; 3] = [Vec::new(), Vec::new(), Vec::new()];
    for (slot, start, v) in segments {
        let plane = &mut planes[slot];
        if plane.capacity() == 0 {
            plane.reserve_exact(n);
        }
        if start != plane.len() {
            return Err(DecodeError::Exr(format!(
                "chunks overlap or leave a gap in channel {} at sample {start}",
                ["R", "G", "B"][slot]
            )));
        }
        plane.extend_from_slice(&v);
    }
    let filled = [planes[0].len(), planes[1].len(), planes[2].len()];
    if filled != [n; 3] {
        return Err(incomplete(filled, n));
    }
    let [r, g, b] = planes;
    Ok(DecodedImage {
        format: CaptureFormat::Exr,
        width: w,
        height: h,
        pixels: Pixels::Planar([r, g, b]),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn attribute(out: &mut Vec<u8>, name: &str, kind: &str, value: &[u8]) {
        out.extend_from_slice(name.as_bytes());
        out.push(0);
        out.extend_from_slice(kind.as_bytes());
        out.push(0);
        out.extend_from_slice(&(value.len() as i32).to_le_bytes());
        out.extend_from_slice(value);
    }

    #[test]
    fn exr_header_size_follows_the_framing() {
        let mut b = vec![0x76, 0x2f, 0x31, 0x01, 2, 0, 0, 0];
        attribute(&mut b, "compression", "compression", &[3]);
        attribute(&mut b, "note", "string", b"hello");
        b.push(0);
        let end = b.len();
        b.extend_from_slice(&[9; 40]); // offset table and chunks
        let h = exr_header_size(&b);
        assert_eq!((h.bytes, h.items), (end, 3));
        // two parts, then the empty header that ends the list
        let mut m = vec![0x76, 0x2f, 0x31, 0x01, 2, 0x10, 0, 0];
        for _ in 0..2 {
            attribute(&mut m, "name", "string", b"p");
            m.push(0);
        }
        m.push(0);
        let end = m.len();
        m.extend_from_slice(&[9; 16]);
        let h = exr_header_size(&m);
        assert_eq!((h.bytes, h.items), (end, 4));
        // a size past the end of the file: all of it, and the attributes seen
        let mut t = vec![0x76, 0x2f, 0x31, 0x01, 2, 0, 0, 0];
        attribute(&mut t, "a", "x", &[]);
        t.extend_from_slice(b"b\0x\0");
        t.extend_from_slice(&i32::MAX.to_le_bytes());
        let h = exr_header_size(&t);
        assert_eq!((h.bytes, h.items), (t.len(), 3));
        // a negative size, a missing NUL, an empty file
        let mut n = vec![0x76, 0x2f, 0x31, 0x01, 2, 0, 0, 0];
        n.extend_from_slice(b"a\0x\0");
        n.extend_from_slice(&(-4i32).to_le_bytes());
        assert_eq!(exr_header_size(&n).bytes, n.len());
        assert_eq!(exr_header_size(b"v/1\x01\x02\0\0\0abc").bytes, 11);
        assert_eq!(exr_header_size(&[]).bytes, 0);
    }

    #[test]
    fn hdr_header_size_ends_after_the_resolution_line() {
        let b = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 2 +X 2\n\x01\x02\x03";
        let h = hdr_header_size(b);
        assert_eq!((h.bytes, h.items), (b.len() - 3, 5));
        let no_blank = b"#?RADIANCE\nA=1\nB=2\n";
        assert_eq!(hdr_header_size(no_blank).bytes, no_blank.len());
        let no_resolution_end = b"#?RADIANCE\n\n-Y 2";
        assert_eq!(
            hdr_header_size(no_resolution_end).bytes,
            no_resolution_end.len()
        );
    }

    fn dwa_leader(c: [u64; 11]) -> Vec<u8> {
        let mut v: Vec<u8> = c.iter().flat_map(|x| x.to_le_bytes()).collect();
        v.extend_from_slice(&[0; 20]);
        v
    }

    #[test]
    fn dwa_counters_must_fit_the_block() {
        // a 100×32 block of RGB half: 19,200 bytes, 104×32 padded: 19,968
        let (bpp, w, h) = (6, 100, 32);
        // lossy RGB: 63 AC and 1 DC coefficient per 8×8 tile of each channel
        let tiles = 13 * 4 * 3;
        let ok = dwa_leader([2, 0, 0, 500, 40, 0, 0, 0, 63 * tiles, tiles, 0]);
        assert_eq!(check_dwa_counters(&ok, bpp, w, h), Ok(()));
        // RLE channels: packed may exceed unpacked a little
        let rle = dwa_leader([2, 0, 0, 0, 0, 600, 19_400, 19_200, 0, 0, 0]);
        assert_eq!(check_dwa_counters(&rle, bpp, w, h), Ok(()));
        for bad in [
            [2, 1 << 40, 0, 0, 0, 0, 0, 0, 0, 0, 0],
            [2, 0, 0, 0, 0, 0, 0, 0, i64::MAX as u64, 0, 0],
            [2, 0, 0, 0, 0, 0, 0, 0, 0, u64::MAX, 0],
            [2, 0, 0, 0, 0, 0, 1 << 31, 100, 0, 0, 0],
            [2, 10_000, 0, 0, 0, 0, 0, 10_000, 0, 0, 0],
        ] {
            assert!(
                matches!(
                    check_dwa_counters(&dwa_leader(bad), bpp, w, h),
                    Err(DecodeError::Exr(_))
                ),
                "{bad:?}"
            );
        }
        // stored raw (exactly the block's size) or empty: no counters to check
        let raw = vec![0xff; 19_200];
        assert_eq!(check_dwa_counters(&raw, bpp, w, h), Ok(()));
        assert_eq!(check_dwa_counters(&[], bpp, w, h), Ok(()));
        // too short for the counters: left to `exr`
        assert_eq!(check_dwa_counters(&[0xff; 40], bpp, w, h), Ok(()));
    }

    #[test]
    fn lines_convert_aligned_or_not() {
        use exr::meta::attribute::SampleType;
        let halves: Vec<u8> = [1.0f32, -2.5, 65504.0]
            .iter()
            .flat_map(|&v| half::f16::from_f32(v).to_bits().to_ne_bytes())
            .collect();
        let floats: Vec<u8> = [1.0f32, -2.5, 1e30]
            .iter()
            .flat_map(|v| v.to_ne_bytes())
            .collect();
        let uints: Vec<u8> = [0u32, 7, u32::MAX]
            .iter()
            .flat_map(|v| v.to_ne_bytes())
            .collect();
        for (bytes, st, want) in [
            (&halves, SampleType::F16, [1.0, -2.5, 65504.0]),
            (&floats, SampleType::F32, [1.0, -2.5, 1e30]),
            (&uints, SampleType::U32, [0.0, 7.0, u32::MAX as f32]),
        ] {
            // the same bytes at an odd address take the unaligned path
            let mut shifted = vec![0u8];
            shifted.extend_from_slice(bytes);
            for src in [&bytes[..], &shifted[1..]] {
                let mut dst = [0f32; 3];
                assert_eq!(convert_line(src, &mut dst, st), Ok(()));
                assert_eq!(dst, want);
            }
            let mut short = [0f32; 2];
            assert!(convert_line(bytes, &mut short, st).is_err());
        }
    }
}
