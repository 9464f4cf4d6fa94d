//! Memory bounds of the decoder under hostile input, measured with a counting global allocator:
//! - the crafted OpenEXR files in `tests/reference/images/crafted/` (headers that claim 200 and
//!   5,003 channels over a megapixel or two, see the README there) are refused or fail while
//!   allocating a small fraction of what their headers imply;
//! - headers built from many tiny attributes are refused before they are parsed;
//! - a valid file with 200 extra channels decodes while only R, G and B are materialised;
//! - deterministic mutations of every file in `tests/reference/images/valid/` (bit flips, byte
//!   overwrites, truncations, duplicated and removed ranges, header and chunk integers set to
//!   extreme values) decode to `Ok` or an error, never a panic past `decode`, and the peak
//!   allocation of each call stays within `required_bytes` (and so within the budget) plus a
//!   fixed slack — on one thread and on the threaded block path.
//!
//! Every test holds `SERIAL` while it measures: the allocator counts all threads of the
//! process, so two tests measuring at once would see each other's allocations.
//!
//! `GW_FUZZ_SCALE` (default 1) multiplies the number of mutations per file.

use goniowatch::decode::{decode, required_bytes, DecodeError, DecodeLimits};
use std::alloc::{GlobalAlloc, Layout, System};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Mutex, MutexGuard, Once};
use std::time::Instant;

// ---------------------------------------------------------------------------------------------
// counting allocator

struct Counting;

static CURRENT: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

fn grew(by: usize) {
    let now = CURRENT.fetch_add(by, Ordering::Relaxed) + by;
    PEAK.fetch_max(now, Ordering::Relaxed);
}

// SAFETY: every call is forwarded to `System` unchanged; the counters only observe sizes.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            grew(layout.size());
        }
        p
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        let p = unsafe { System.alloc_zeroed(layout) };
        if !p.is_null() {
            grew(layout.size());
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) };
        CURRENT.fetch_sub(layout.size(), Ordering::Relaxed);
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if !p.is_null() {
            if new_size >= layout.size() {
                grew(new_size - layout.size());
            } else {
                CURRENT.fetch_sub(layout.size() - new_size, Ordering::Relaxed);
            }
        }
        p
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

static SERIAL: Mutex<()> = Mutex::new(());

fn serial() -> MutexGuard<'static, ()> {
    SERIAL
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// Run `f` and return its result with the peak of live bytes above the level at the start.
fn peak_of<T>(f: impl FnOnce() -> T) -> (T, usize) {
    let start = CURRENT.load(Ordering::Relaxed);
    PEAK.store(start, Ordering::Relaxed);
    let r = f();
    let peak = PEAK.load(Ordering::Relaxed).saturating_sub(start);
    (r, peak)
}

const MIB: usize = 1 << 20;

// ---------------------------------------------------------------------------------------------
// files

fn images() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/reference/images")
}

fn read(path: &Path) -> Vec<u8> {
    std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn limits(max_bytes: u64, threads: usize) -> DecodeLimits {
    DecodeLimits {
        threads,
        max_bytes,
        ..DecodeLimits::default()
    }
}

// ---------------------------------------------------------------------------------------------
// hand-built OpenEXR headers

fn attribute(out: &mut Vec<u8>, name: &str, kind: &str, value: &[u8]) {
    out.extend_from_slice(name.as_bytes());
    out.push(0);
    out.extend_from_slice(kind.as_bytes());
    out.push(0);
    out.extend_from_slice(&(value.len() as i32).to_le_bytes());
    out.extend_from_slice(value);
}

fn box2i(w: i32, h: i32) -> Vec<u8> {
    [0, 0, w - 1, h - 1]
        .iter()
        .flat_map(|v: &i32| v.to_le_bytes())
        .collect()
}

/// OpenEXR compression codes.
const ZIP: u8 = 3;
const PIZ: u8 = 4;

fn channel_names(extra: usize) -> Vec<String> {
    let mut names = vec!["B".to_string(), "G".to_string(), "R".to_string()];
    names.extend((0..extra).map(|i| format!("c{i:04}")));
    names
}

/// The attributes every OpenEXR header needs, for half channels `names` (sorted) over
/// `w`×`h` pixels.
fn required_attributes(b: &mut Vec<u8>, names: &[String], w: i32, h: i32, compression: u8) {
    let mut chlist = Vec::new();
    for name in names {
        chlist.extend_from_slice(name.as_bytes());
        chlist.push(0);
        chlist.extend_from_slice(&1i32.to_le_bytes()); // HALF
        chlist.extend_from_slice(&[0, 0, 0, 0]); // pLinear, reserved
        chlist.extend_from_slice(&1i32.to_le_bytes()); // x sampling
        chlist.extend_from_slice(&1i32.to_le_bytes()); // y sampling
    }
    chlist.push(0);
    attribute(b, "channels", "chlist", &chlist);
    attribute(b, "compression", "compression", &[compression]);
    attribute(b, "dataWindow", "box2i", &box2i(w, h));
    attribute(b, "displayWindow", "box2i", &box2i(w, h));
    attribute(b, "lineOrder", "lineOrder", &[0]);
    attribute(b, "pixelAspectRatio", "float", &1f32.to_le_bytes());
    let centre: Vec<u8> = [0f32, 0f32].iter().flat_map(|v| v.to_le_bytes()).collect();
    attribute(b, "screenWindowCenter", "v2f", &centre);
    attribute(b, "screenWindowWidth", "float", &1f32.to_le_bytes());
}

fn lines_per_chunk(compression: u8) -> usize {
    match compression {
        ZIP => 16,
        PIZ => 32,
        _ => 1,
    }
}

/// A single-part scan-line OpenEXR file with half channels B, G, R and `extra` more
/// (`c0000`, `c0001`, …), `w`×`h` pixels, and `custom` tiny custom attributes. It holds the
/// header and the offset table; the table points at the end of the file, where the chunks
/// would start: a decoder learns that they are missing only when it reads the first one.
fn crafted_exr(extra: usize, w: i32, h: i32, compression: u8, custom: usize) -> Vec<u8> {
    let mut b = vec![0x76, 0x2f, 0x31, 0x01, 2, 0, 0, 0];
    required_attributes(&mut b, &channel_names(extra), w, h, compression);
    // the shortest distinct names: three characters of 62
    const ALPHABET: &[u8] = b"abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789";
    for i in 0..custom {
        let name: String = [i / (62 * 62), i / 62, i]
            .iter()
            .map(|&k| ALPHABET[k % 62] as char)
            .collect();
        attribute(&mut b, &name, "x", &[]);
    }
    b.push(0);
    let chunks = (h as usize).div_ceil(lines_per_chunk(compression));
    let end = (b.len() + chunks * 8) as u64;
    for _ in 0..chunks {
        b.extend_from_slice(&end.to_le_bytes());
    }
    b
}

/// A two-part scan-line file: part 0 is a complete, uncompressed 16×16 half RGB image, part 1
/// has `extra` half channels over `w`×16·`w` pixels with ZIP compression and no chunks. Returns
/// the file and the offset of part 0's first chunk.
fn two_part_exr(extra: usize, w: i32) -> (Vec<u8>, usize) {
    let parts = [
        ("rgb", channel_names(0), 16, 16, 0u8),
        ("aov", channel_names(extra)[3..].to_vec(), w, 16, ZIP),
    ];
    let mut b = vec![0x76, 0x2f, 0x31, 0x01, 2, 0x10, 0, 0];
    for (name, names, w, h, compression) in &parts {
        required_attributes(&mut b, names, *w, *h, *compression);
        let mut text = |key: &str, value: &str| attribute(&mut b, key, "string", value.as_bytes());
        text("name", name);
        text("type", "scanlineimage");
        let chunks = (*h as usize).div_ceil(lines_per_chunk(*compression)) as i32;
        attribute(&mut b, "chunkCount", "int", &chunks.to_le_bytes());
        b.push(0);
    }
    b.push(0);
    let table = b.len();
    b.resize(table + 8 * (16 + 1), 0);
    let first = b.len();
    for y in 0..16i32 {
        let at = b.len() as u64;
        b[table + 8 * y as usize..table + 8 * y as usize + 8].copy_from_slice(&at.to_le_bytes());
        b.extend_from_slice(&0i32.to_le_bytes()); // part
        b.extend_from_slice(&y.to_le_bytes());
        b.extend_from_slice(&96i32.to_le_bytes());
        for _ in 0..16 * 3 {
            b.extend_from_slice(&half::f16::from_f32(0.5).to_bits().to_le_bytes());
        }
    }
    let end = (b.len() as u64).to_le_bytes();
    b[table + 8 * 16..table + 8 * 17].copy_from_slice(&end);
    (b, first)
}

/// The stored crafted files: (name, bytes, channels, width, height).
fn crafted_files() -> Vec<(&'static str, Vec<u8>, usize, usize, usize)> {
    vec![
        (
            "channels200_half_zip.exr",
            crafted_exr(200, 1000, 1000, ZIP, 0),
            203,
            1000,
            1000,
        ),
        (
            "channels5000_half_piz.exr",
            crafted_exr(5000, 1400, 1400, PIZ, 0),
            5003,
            1400,
            1400,
        ),
    ]
}

/// Writes the crafted files. Run after changing the generator:
/// `cargo test --test decode_fuzz -- --ignored write_crafted_files`
#[test]
#[ignore]
fn write_crafted_files() {
    let dir = images().join("crafted");
    std::fs::create_dir_all(&dir).expect("create crafted dir");
    for (name, bytes, ..) in crafted_files() {
        std::fs::write(dir.join(name), &bytes).expect("write crafted file");
        println!("{name}: {} bytes", bytes.len());
    }
}

#[test]
fn crafted_files_match_their_generator() {
    for (name, bytes, ..) in crafted_files() {
        let stored = read(&images().join("crafted").join(name));
        assert!(stored == bytes, "{name} differs from its generator");
        assert!(stored.len() < 200_000, "{name}: {} bytes", stored.len());
    }
}

// ---------------------------------------------------------------------------------------------
// crafted files and header bombs

/// What the header of a crafted file implies when every channel is materialised: its half
/// samples plus the f32 R, G, B planes.
fn all_channels_bytes(channels: usize, w: usize, h: usize) -> usize {
    channels * w * h * 2 + 3 * w * h * 4
}

#[test]
fn crafted_many_channel_files_stay_far_below_what_their_headers_imply() {
    let _serial = serial();
    for (name, _, channels, w, h) in crafted_files() {
        let bytes = read(&images().join("crafted").join(name));
        let implied = all_channels_bytes(channels, w, h);
        for threads in [1, 2] {
            for max_bytes in [256 << 20, DecodeLimits::default().max_bytes] {
                let lim = limits(max_bytes, threads);
                let (r, peak) = peak_of(|| decode(&bytes, &lim));
                println!(
                    "{name}, {threads} thread(s), budget {} MiB: peak {:.1} MiB of {} MiB \
                     implied by all channels: {r:?}",
                    max_bytes >> 20,
                    peak as f64 / MIB as f64,
                    implied / MIB
                );
                assert!(peak < 64 * MIB, "{name}: peak {peak}");
                assert!(peak < implied / 8, "{name}: peak {peak}");
                match (&r, channels) {
                    // 5,003 channels: one PIZ block of 32 lines is 448 MB on its own
                    (
                        Err(DecodeError::OverBudget {
                            needed,
                            budget,
                            channels: c,
                            pixels,
                            ..
                        }),
                        5003,
                    ) => {
                        assert_eq!((*c, *pixels), (5003, (w * h) as u64));
                        assert!(needed > budget);
                        let msg = r.as_ref().unwrap_err().to_string();
                        assert!(msg.contains("max_bytes"), "{msg}");
                        assert!(msg.contains("5003 channels"), "{msg}");
                    }
                    // 200 channels: only R, G, B and one block are ever allocated, well
                    // within budget; the missing chunks are an error
                    (Err(DecodeError::Exr(_)), 203) => {}
                    _ => panic!("{name}, {threads} thread(s): unexpected {r:?}"),
                }
            }
        }
    }
    // a budget below one block and the planes refuses the 200-channel file too
    let bytes = read(&images().join("crafted/channels200_half_zip.exr"));
    let (r, peak) = peak_of(|| decode(&bytes, &limits(16 << 20, 1)));
    assert!(
        matches!(r, Err(DecodeError::OverBudget { channels: 203, .. })),
        "{r:?}"
    );
    assert!(peak < 4 * MIB, "{peak}");
}

#[test]
fn huge_headers_are_refused_before_they_are_parsed() {
    let _serial = serial();
    // OpenEXR: 60,000 custom attributes of 10 bytes each (600 kB)
    let exr = crafted_exr(0, 16, 16, ZIP, 60_000);
    // Radiance: 600,000 lines of one byte or two (1.2 to 1.8 MB)
    let hdr = |line: &[u8]| {
        let mut b = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n".to_vec();
        for _ in 0..600_000 {
            b.extend_from_slice(line);
        }
        b.extend_from_slice(b"\n-Y 1 +X 1\n\x80\x80\x80\x80");
        b
    };
    let (hdr1, hdr2, hdr3) = (hdr(b"=\n"), hdr(b"a=\n"), hdr(b"=a\n"));
    for (name, bytes) in [
        ("exr", &exr),
        ("hdr =", &hdr1),
        ("hdr a=", &hdr2),
        ("hdr =a", &hdr3),
    ] {
        // within a small budget: refused with nothing parsed
        let (r, peak) = peak_of(|| decode(bytes, &limits(64 << 20, 1)));
        println!(
            "{name} header bomb, 64 MiB budget: peak {:.2} MiB: {r:?}",
            peak as f64 / MIB as f64
        );
        assert!(
            matches!(r, Err(DecodeError::OverBudget { header_bytes, .. }) if header_bytes as usize >= bytes.len() / 2),
            "{r:?}"
        );
        assert!(peak < MIB, "{peak}");
        // within a large one: parsed, and the parse stays within the estimate
        let lim = limits(1 << 30, 1);
        let need = required_bytes(bytes, &lim).expect("estimate") as usize;
        let (r, peak) = peak_of(|| decode(bytes, &lim));
        println!(
            "{name} header bomb, 1 GiB budget: peak {:.1} MiB of {:.1} MiB estimated \
             ({:.0} bytes per header byte): {:?}",
            peak as f64 / MIB as f64,
            need as f64 / MIB as f64,
            peak as f64 / bytes.len() as f64,
            r.as_ref().map(|_| ())
        );
        assert!(peak <= need, "{name}: peak {peak} > estimate {need}");
    }
}

#[test]
fn extra_channels_are_not_materialised() {
    use exr::prelude::*;
    let _serial = serial();
    let (w, h) = (256usize, 256usize);
    let value = |c: usize, i: usize| f16::from_f32((c * 7 + i % 13) as f32 * 0.25);
    let mut list: SmallVec<[AnyChannel<FlatSamples>; 4]> = SmallVec::new();
    for (c, name) in ["R", "G", "B"].iter().enumerate() {
        let v: Vec<f16> = (0..w * h).map(|i| value(c, i)).collect();
        list.push(AnyChannel::new(*name, FlatSamples::F16(v)));
    }
    for c in 0..200 {
        list.push(AnyChannel::new(
            format!("c{c:03}").as_str(),
            FlatSamples::F16(vec![f16::from_f32(c as f32); w * h]),
        ));
    }
    let layer = Layer::new(
        (w, h),
        LayerAttributes::default(),
        Encoding {
            compression: Compression::ZIP16,
            blocks: Blocks::ScanLines,
            line_order: LineOrder::Increasing,
        },
        AnyChannels::sort(list),
    );
    let mut bytes = Vec::new();
    Image::from_layer(layer)
        .write()
        .non_parallel()
        .to_buffered(std::io::Cursor::new(&mut bytes))
        .expect("write");
    let implied = all_channels_bytes(203, w, h);
    for threads in [1, 2] {
        let lim = limits(256 << 20, threads);
        let need = required_bytes(&bytes, &lim).expect("estimate") as usize;
        let (img, peak) = peak_of(|| decode(&bytes, &lim));
        let img = img.expect("decode");
        println!(
            "valid 203-channel file, {threads} thread(s): peak {:.1} MiB, estimate {:.1} MiB, \
             all channels {:.1} MiB",
            peak as f64 / MIB as f64,
            need as f64 / MIB as f64,
            implied as f64 / MIB as f64
        );
        for (i, px) in [(0usize, 0usize), (17, 3), (255, 255)] {
            let k = px * w + i;
            let got = img.pixel(i, px).expect("pixel");
            for c in 0..3 {
                assert_eq!(got[c], value(c, k).to_f32());
            }
        }
        assert!(peak <= need, "peak {peak} > estimate {need}");
        // one thread: the planes and one block; two: also the chunks and the decoded lines
        assert!(peak < implied / (6 - 2 * threads), "peak {peak}");
    }
}

// ---------------------------------------------------------------------------------------------
// mutations

/// xorshift64* with a fixed seed per file, so every run feeds the same inputs.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }

    fn below(&mut self, n: usize) -> usize {
        if n == 0 {
            0
        } else {
            (self.next() % n as u64) as usize
        }
    }

    fn pick<T: Copy>(&mut self, v: &[T]) -> T {
        v[self.below(v.len())]
    }
}

const HUGE_I32: &[i32] = &[
    0,
    1,
    -1,
    2,
    255,
    32767,
    32768,
    65535,
    65536,
    1 << 20,
    1 << 24,
    1 << 30,
    0x7fff_fff0,
    i32::MAX,
    i32::MIN,
    -(1 << 30),
];

/// Byte ranges of an OpenEXR file worth aiming at: attribute values, the offset table, and
/// the first bytes of each chunk (part number, coordinates, data size).
struct ExrMap {
    values: Vec<(usize, usize)>,
    table: (usize, usize),
    chunks: Vec<usize>,
}

fn exr_map(b: &[u8]) -> Option<ExrMap> {
    let nul = |pos: usize| -> Option<usize> {
        Some(pos + b.get(pos..)?.iter().position(|&c| c == 0)? + 1)
    };
    let mut values = Vec::new();
    let mut pos = 8;
    loop {
        let after_name = nul(pos)?;
        if after_name == pos + 1 {
            pos = after_name;
            break;
        }
        let after_type = nul(after_name)?;
        let size = i32::from_le_bytes(b.get(after_type..after_type + 4)?.try_into().ok()?);
        let start = after_type + 4;
        let size = usize::try_from(size).ok()?;
        values.push((start, size));
        pos = start + size;
    }
    let first = u64::from_le_bytes(b.get(pos..pos + 8)?.try_into().ok()?) as usize;
    let table_end = if first > pos && first <= b.len() {
        first
    } else {
        pos
    };
    let chunks = b[pos..table_end]
        .chunks_exact(8)
        .map(|c| u64::from_le_bytes(c.try_into().unwrap_or([0; 8])) as usize)
        .filter(|&o| o < b.len())
        .collect();
    Some(ExrMap {
        values,
        table: (pos, table_end),
        chunks,
    })
}

fn put_i32(b: &mut [u8], at: usize, v: i32) {
    if let Some(dst) = b.get_mut(at..at + 4) {
        dst.copy_from_slice(&v.to_le_bytes());
    }
}

/// Set one integer of the header or of a chunk header to an extreme value.
fn huge_field(b: &mut Vec<u8>, rng: &mut Rng, exr: bool) {
    if exr {
        let Some(map) = exr_map(b) else { return };
        match rng.below(3) {
            0 if !map.values.is_empty() => {
                let (start, size) = rng.pick(&map.values);
                if size >= 4 {
                    let at = start + 4 * rng.below(size / 4);
                    put_i32(b, at, rng.pick(HUGE_I32));
                } else if size > 0 {
                    b[start + rng.below(size)] = rng.next() as u8;
                }
            }
            1 if map.table.1 > map.table.0 + 8 => {
                let entries = (map.table.1 - map.table.0) / 8;
                let at = map.table.0 + 8 * rng.below(entries);
                let len = b.len() as u64;
                let v = rng.pick(&[0, 8, len - 1, len, len + 1, u64::MAX, 1 << 40]);
                b[at..at + 8].copy_from_slice(&v.to_le_bytes());
            }
            _ if !map.chunks.is_empty() => {
                let at = rng.pick(&map.chunks) + 4 * rng.below(6);
                put_i32(b, at, rng.pick(HUGE_I32));
            }
            _ => {}
        }
    } else {
        // Radiance: the resolution line, or the width in a run-length scanline header
        if rng.below(2) == 0 {
            let resolution = b.windows(4).position(|w| w == b"\n-Y " || w == b"\n+Y ");
            if let Some(at) = resolution {
                let end = b[at + 1..]
                    .iter()
                    .position(|&c| c == b'\n')
                    .map_or(b.len(), |n| at + 1 + n);
                let dims = rng.pick(&[
                    "-Y 2147483647 +X 2147483647",
                    "-Y 4294967295 +X 1",
                    "-Y 32768 +X 32768",
                    "-Y 30000 +X 8",
                    "-Y 8 +X 30000",
                    "-Y 0 +X 0",
                    "-Y 1 +X 1",
                    "-Y -5 +X 7",
                    "+X 3 -Y 3",
                ]);
                b.splice(at + 1..end, dims.bytes());
                return;
            }
        }
        let starts: Vec<usize> = b
            .windows(2)
            .enumerate()
            .filter(|(_, w)| w == &[2, 2])
            .map(|(i, _)| i)
            .collect();
        if !starts.is_empty() {
            let at = rng.pick(&starts) + 2;
            if at + 2 <= b.len() {
                let random = rng.next() as u16;
                let v = rng.pick(&[0u16, 1, 0x7fff, 0x8000, 0xffff, random]);
                b[at..at + 2].copy_from_slice(&v.to_be_bytes());
            }
        }
    }
}

/// One to three mutations of `orig`.
fn mutate(orig: &[u8], rng: &mut Rng, exr: bool) -> Vec<u8> {
    let mut b = orig.to_vec();
    for _ in 0..1 + rng.below(3) {
        if b.is_empty() {
            break;
        }
        let len = b.len();
        // aim half the byte-level mutations at the header, where the sizes live
        let hot = len.min(if exr { 4096 } else { 256 });
        let pos = |rng: &mut Rng| {
            if rng.below(2) == 0 {
                rng.below(hot)
            } else {
                rng.below(len)
            }
        };
        match rng.below(8) {
            0 => {
                for _ in 0..1 + rng.below(16) {
                    let i = pos(rng);
                    b[i] ^= 1 << rng.below(8);
                }
            }
            1 => {
                for _ in 0..1 + rng.below(8) {
                    let i = pos(rng);
                    b[i] = match rng.below(3) {
                        0 => 0x00,
                        1 => 0xff,
                        _ => rng.next() as u8,
                    };
                }
            }
            2 => {
                let cut = rng.below(len);
                b.truncate(cut);
            }
            3 => {
                let start = pos(rng);
                let n = 1 + rng.below((len - start).min(4096));
                let copy = b[start..start + n].to_vec();
                let at = pos(rng);
                b.splice(at..at, copy);
            }
            4 => {
                let start = pos(rng);
                let n = 1 + rng.below((len - start).min(4096));
                b.drain(start..start + n);
            }
            _ => huge_field(&mut b, rng, exr),
        }
    }
    b
}

/// While set, panics (which `decode` turns into `DecodeError::Panicked`) are tallied by
/// location instead of printed.
static QUIET: AtomicBool = AtomicBool::new(false);
static PANICS: Mutex<BTreeMap<String, usize>> = Mutex::new(BTreeMap::new());
static HOOK: Once = Once::new();

fn quiet_panics() {
    HOOK.call_once(|| {
        let default = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if !QUIET.load(Ordering::Relaxed) {
                return default(info);
            }
            let place = info.location().map_or("?".to_string(), |l| {
                let file = l.file();
                let short = file.rfind("/src/").map_or(file, |i| {
                    let crate_start = file[..i].rfind('/').map_or(0, |j| j + 1);
                    &file[crate_start..]
                });
                format!("{short}:{}", l.line())
            });
            let msg = info
                .payload()
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| info.payload().downcast_ref::<String>().cloned())
                .unwrap_or_default();
            let key = format!("{place} {}", msg.chars().take(60).collect::<String>());
            *PANICS
                .lock()
                .unwrap_or_else(|p| p.into_inner())
                .entry(key)
                .or_default() += 1;
        }));
    });
}

/// Allowance above the estimate for what the measurement itself sees: the test harness's own
/// allocations while a case runs, and allocator rounding.
const SLACK: usize = MIB;

#[derive(Default)]
struct Tally {
    calls: usize,
    ok: usize,
    errors: std::collections::BTreeMap<&'static str, usize>,
    max_peak: usize,
    max_ratio: f64,
    max_ratio_case: String,
}

fn kind(e: &DecodeError) -> &'static str {
    match e {
        DecodeError::Empty => "Empty",
        DecodeError::UnknownFormat(_) => "UnknownFormat",
        DecodeError::Hdr(_) => "Hdr",
        DecodeError::Exr(_) => "Exr",
        DecodeError::NoRgbLayer(_) => "NoRgbLayer",
        DecodeError::DeepData => "DeepData",
        DecodeError::TooLarge { .. } => "TooLarge",
        DecodeError::Panicked(_) => "Panicked",
        DecodeError::OverBudget { .. } => "OverBudget",
        DecodeError::Ldr { .. } => "Ldr",
    }
}

/// Decode `bytes` under `lim`, checking the contract; returns (peak, estimate).
fn check_case(bytes: &[u8], lim: &DecodeLimits, what: &str, tally: &mut Tally) {
    quiet_panics();
    QUIET.store(true, Ordering::Relaxed);
    let need = required_bytes(bytes, lim);
    let (r, peak) = peak_of(|| std::panic::catch_unwind(|| decode(bytes, lim)));
    QUIET.store(false, Ordering::Relaxed);
    let r = r.unwrap_or_else(|_| panic!("{what}: a panic escaped decode"));
    tally.calls += 1;
    match &r {
        Ok(img) => {
            tally.ok += 1;
            assert_eq!(
                img.samples().count(),
                img.width * img.height * 3,
                "{what}: wrong sample count"
            );
        }
        Err(e) => *tally.errors.entry(kind(e)).or_default() += 1,
    }
    tally.max_peak = tally.max_peak.max(peak);
    assert!(
        peak as u64 <= lim.max_bytes + SLACK as u64,
        "{what}: peak {peak} over the budget {}: {r:?}",
        lim.max_bytes
    );
    if let Ok(need) = need {
        let ratio = peak as f64 / need as f64;
        if ratio > tally.max_ratio {
            tally.max_ratio = ratio;
            tally.max_ratio_case = format!("{what}: peak {peak} of {need}");
        }
        assert!(
            peak <= need as usize + SLACK,
            "{what}: peak {peak} over the estimate {need}: {r:?}"
        );
    }
}

/// Mutations per file: many for small files, fewer for large ones (a decode's time grows with
/// the file), so that the whole run takes about half a minute in a debug build on two cores.
fn cases_for(len: usize) -> usize {
    let scale: f64 = std::env::var("GW_FUZZ_SCALE")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(1.0);
    let base = if len > 1 << 20 {
        30
    } else if len > 100_000 {
        100
    } else {
        300
    };
    ((base as f64 * scale).round() as usize).max(1)
}

/// Layouts the reference files lack, written at run time: tiles with mip levels, DWAB with
/// an extra channel, and two parts.
fn generated_corpus() -> Vec<(String, Vec<u8>)> {
    use exr::prelude::*;
    let rgb = |Vec2(x, y): Vec2<usize>| {
        let v = (x * 3 + y * 5) as f32 * 0.01;
        (
            f16::from_f32(v),
            f16::from_f32(v * 0.5),
            f16::from_f32(1.0 - v),
        )
    };
    let write = |image: &Image<Layer<AnyChannels<FlatSamples>>>| {
        let mut bytes = Vec::new();
        image
            .write()
            .non_parallel()
            .to_buffered(std::io::Cursor::new(&mut bytes))
            .expect("write");
        bytes
    };
    let mut out = Vec::new();

    let tiled = Image::from_layer(Layer::new(
        (67, 45),
        LayerAttributes::default(),
        Encoding {
            compression: Compression::ZIP16,
            blocks: Blocks::Tiles(Vec2(16, 16)),
            line_order: LineOrder::Increasing,
        },
        SpecificChannels::rgb(rgb),
    ));
    let mut bytes = Vec::new();
    tiled
        .write()
        .non_parallel()
        .to_buffered(std::io::Cursor::new(&mut bytes))
        .expect("write tiled");
    out.push(("generated_tiled_zip.exr".to_string(), bytes));

    let (w, h) = (70, 300);
    let mut list: SmallVec<[AnyChannel<FlatSamples>; 4]> = SmallVec::new();
    for (c, name) in ["R", "G", "B", "Z"].iter().enumerate() {
        let v: Vec<f32> = (0..w * h)
            .map(|i| ((i * (c + 1)) % 97) as f32 * 0.1)
            .collect();
        list.push(AnyChannel::new(*name, FlatSamples::F32(v)));
    }
    let dwab = Image::from_layer(Layer::new(
        (w, h),
        LayerAttributes::default(),
        Encoding {
            compression: Compression::DWAB(None),
            blocks: Blocks::ScanLines,
            line_order: LineOrder::Increasing,
        },
        AnyChannels::sort(list),
    ));
    out.push(("generated_dwab_f32.exr".to_string(), write(&dwab)));

    out.push(("generated_two_part.exr".to_string(), two_part_exr(40, 64).0));

    // low-dynamic-range captures: PNG 8 and 16 bit, JPEG
    {
        use image::{ExtendedColorType, ImageEncoder};
        let (w, h) = (97u32, 61u32);
        let rgb8: Vec<u8> = (0..w * h * 3).map(|i| (i * 7 % 251) as u8).collect();
        let mut png8 = Vec::new();
        image::codecs::png::PngEncoder::new(&mut png8)
            .write_image(&rgb8, w, h, ExtendedColorType::Rgb8)
            .expect("png8");
        out.push(("generated_rgb8.png".to_string(), png8));
        let rgb16: Vec<u8> = (0..w * h * 3)
            .flat_map(|i| ((i * 977 % 65521) as u16).to_ne_bytes())
            .collect();
        let mut png16 = Vec::new();
        image::codecs::png::PngEncoder::new(&mut png16)
            .write_image(&rgb16, w, h, ExtendedColorType::Rgb16)
            .expect("png16");
        out.push(("generated_rgb16.png".to_string(), png16));
        let mut jpeg = Vec::new();
        image::codecs::jpeg::JpegEncoder::new_with_quality(&mut jpeg, 90)
            .write_image(&rgb8, w, h, ExtendedColorType::Rgb8)
            .expect("jpeg");
        out.push(("generated_rgb8.jpg".to_string(), jpeg));
    }
    for (name, bytes) in &out {
        decode(bytes, &DecodeLimits::default()).unwrap_or_else(|e| panic!("{name}: {e}"));
    }
    out
}

#[test]
fn mutated_valid_files_stay_within_the_budget() {
    let _serial = serial();
    let budget: u64 = 256 << 20;
    let mut names: Vec<PathBuf> = std::fs::read_dir(images().join("valid"))
        .expect("valid dir")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| matches!(p.extension().and_then(|e| e.to_str()), Some("exr" | "hdr")))
        .collect();
    names.sort();
    assert!(names.len() >= 15, "{names:?}");
    let mut corpus: Vec<(String, Vec<u8>)> = names
        .iter()
        .map(|path| {
            let name = path
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default();
            (name, read(path))
        })
        .collect();
    corpus.extend(generated_corpus());
    let t0 = Instant::now();
    let mut total = Tally::default();
    for (name, orig) in &corpus {
        let exr = name.ends_with(".exr");
        let seed = name.bytes().fold(0x9e37_79b9_7f4a_7c15u64, |h, c| {
            (h ^ c as u64).wrapping_mul(0x100_0000_01b3)
        });
        let mut rng = Rng(seed | 1);
        let mut tally = Tally::default();
        let t = Instant::now();
        let cases = cases_for(orig.len());
        for case in 0..cases {
            let b = mutate(orig, &mut rng, exr);
            for threads in [1, 2] {
                let what = format!("{name} case {case} threads {threads}");
                check_case(&b, &limits(budget, threads), &what, &mut tally);
            }
        }
        println!(
            "{name:28} {cases:4} mutations × 2: {:3} ok, errors {:?}, max peak {:6.2} MiB, \
             max peak/estimate {:.2}, {:.1} s",
            tally.ok,
            tally.errors,
            tally.max_peak as f64 / MIB as f64,
            tally.max_ratio,
            t.elapsed().as_secs_f64()
        );
        total.calls += tally.calls;
        total.ok += tally.ok;
        for (k, v) in tally.errors {
            *total.errors.entry(k).or_default() += v;
        }
        total.max_peak = total.max_peak.max(tally.max_peak);
        if tally.max_ratio > total.max_ratio {
            total.max_ratio = tally.max_ratio;
            total.max_ratio_case = tally.max_ratio_case;
        }
    }
    println!(
        "all: {} decodes, {} ok, errors {:?}, max peak {:.2} MiB, max peak/estimate {:.2}, {:.1} s",
        total.calls,
        total.ok,
        total.errors,
        total.max_peak as f64 / MIB as f64,
        total.max_ratio,
        t0.elapsed().as_secs_f64()
    );
    println!("closest to the estimate: {}", total.max_ratio_case);
    for (place, n) in PANICS.lock().unwrap_or_else(|p| p.into_inner()).iter() {
        println!("caught panic ×{n}: {place}");
    }
}

/// DWA chunks start with eleven u64 counters, five of which size buffers before any data is
/// read (the raw "unknown" section, the RLE section before and after unpacking, the AC and DC
/// coefficient counts). Claims far beyond the block are refused before `exr` sees them.
#[test]
fn dwa_chunk_counters_cannot_size_buffers() {
    let _serial = serial();
    let orig = read(&images().join("valid/f32_dwaa.exr"));
    let map = exr_map(&orig).expect("framing");
    assert!(!map.chunks.is_empty());
    for counter in [1usize, 6, 7, 8, 9] {
        for value in [1u64 << 31, 1 << 40, i64::MAX as u64] {
            for &chunk in map.chunks.iter().take(2) {
                let mut b = orig.clone();
                // scan-line chunk: y, data size, then the DWA counters
                let at = chunk + 8 + 8 * counter;
                b[at..at + 8].copy_from_slice(&value.to_le_bytes());
                for threads in [1, 2] {
                    let lim = limits(256 << 20, threads);
                    let need = required_bytes(&b, &lim).expect("estimate") as usize;
                    quiet_panics();
                    QUIET.store(true, Ordering::Relaxed);
                    let (r, peak) = peak_of(|| decode(&b, &lim));
                    QUIET.store(false, Ordering::Relaxed);
                    assert!(
                        peak <= need + SLACK,
                        "counter {counter} = {value}: peak {peak} > estimate {need}: {r:?}"
                    );
                    assert!(r.is_err(), "counter {counter} = {value}");
                }
            }
        }
    }
}

/// A chunk names its own part, and `exr` sizes the chunk's data by that part's block before
/// anything checks the part: a chunk of the RGB part that names a part with thousands of
/// channels allocates that part's block. The estimate counts it, and a budget below it refuses
/// the file.
#[test]
fn a_chunk_cannot_borrow_a_larger_part_for_its_size() {
    let _serial = serial();
    let (orig, first) = two_part_exr(2000, 1400);
    let good = decode(&orig, &limits(256 << 20, 1)).expect("two-part file");
    assert_eq!((good.width, good.height), (16, 16));
    assert_eq!(good.pixel(3, 5), Some([0.5, 0.5, 0.5]));
    // the largest size `exr` accepts for a chunk of part 1: its block
    let block = 2000 * 2 * 1400 * 16;
    let mut b = orig.clone();
    b[first..first + 4].copy_from_slice(&1i32.to_le_bytes());
    b[first + 8..first + 12].copy_from_slice(&(block as i32).to_le_bytes());
    for threads in [1, 2] {
        let lim = limits(256 << 20, threads);
        let need = required_bytes(&b, &lim).expect("estimate") as usize;
        let (r, peak) = peak_of(|| decode(&b, &lim));
        println!(
            "chunk naming the 2000-channel part, {threads} thread(s): peak {:.1} MiB, \
             estimate {:.1} MiB: {r:?}",
            peak as f64 / MIB as f64,
            need as f64 / MIB as f64
        );
        assert!(r.is_err());
        assert!(
            need > block && peak <= need + SLACK,
            "peak {peak}, estimate {need}"
        );
        let (r, peak) = peak_of(|| decode(&b, &limits(64 << 20, threads)));
        assert!(matches!(r, Err(DecodeError::OverBudget { .. })), "{r:?}");
        assert!(peak < MIB, "{peak}");
    }
}
