//! Shell: reading announced capture files safely and turning them into `Outcome`s.
//!
//! - The file name comes from the wire, so it is untrusted: absolute paths, `..`, and links that
//!   leave the capture root are refused.
//! - A file that appears is not a finished file: it is accepted once it decodes and its size did
//!   not change while it was read (a rename into place gives that at once); a file that is
//!   absent, still growing, or does not decode is retried with backoff, and after the limit it is
//!   recorded as missing or failed. The file is never moved, changed or deleted.
//! - Decoding runs on a bounded pool of worker threads (crossbeam-channel); the caller keeps
//!   jobs it could not queue, so a slow disk pushes back instead of piling up.

use crate::checks::Outcome;
use crate::config::{IngestSpec, MAX_GIVE_UP_S};
use crate::decode::{decode, DecodeLimits};
use crate::measure::averaging::{average, AverageOptions};
use sha2::{Digest, Sha256};
use std::path::{Component, Path, PathBuf};
use std::time::{Duration, Instant};
use thiserror::Error;

#[derive(Debug, Error, PartialEq)]
pub(crate) enum PathError {
    #[error("file name is empty")]
    Empty,
    #[error("absolute file name '{0}' refused (names are relative to the capture root)")]
    Absolute(String),
    #[error("file name '{0}' refused: it climbs out of the capture root with '..'")]
    ParentDir(String),
    #[error("file '{0}' refused: it resolves outside the capture root (a link?)")]
    OutsideRoot(String),
}

/// Resolve an announced name under `root`. Lexical checks first; then, if the file exists, its
/// canonical path must stay under the canonical root (so a symlink cannot leave it).
pub(crate) fn resolve(root: &Path, name: &str) -> Result<PathBuf, PathError> {
    if name.is_empty() {
        return Err(PathError::Empty);
    }
    let rel = Path::new(name);
    for c in rel.components() {
        match c {
            Component::Normal(_) | Component::CurDir => {}
            Component::ParentDir => return Err(PathError::ParentDir(name.into())),
            Component::RootDir | Component::Prefix(_) => {
                return Err(PathError::Absolute(name.into()))
            }
        }
    }
    let path = root.join(rel);
    if let (Ok(real), Ok(real_root)) = (path.canonicalize(), root.canonicalize()) {
        if !real.starts_with(&real_root) {
            return Err(PathError::OutsideRoot(name.into()));
        }
    }
    Ok(path)
}

/// The decoder's limits for an `[ingest]` spec.
pub(crate) fn decode_limits(spec: &IngestSpec) -> DecodeLimits {
    DecodeLimits {
        threads: spec.decode_threads.max(1),
        max_bytes: spec.max_decode_mib.saturating_mul(1 << 20),
        ..DecodeLimits::default()
    }
}

/// Why one attempt at a capture file failed.
#[derive(Debug, Clone, PartialEq)]
pub struct AttemptError {
    pub reason: String,
    /// The file's size when it was seen (None: it could not be opened).
    pub size: Option<u64>,
    /// Retrying cannot help (not a regular file, too large, outside the root).
    pub permanent: bool,
}

impl AttemptError {
    fn retry(reason: String, size: Option<u64>) -> Self {
        AttemptError {
            reason,
            size,
            permanent: false,
        }
    }
    fn permanent(reason: String, size: Option<u64>) -> Self {
        AttemptError {
            reason,
            size,
            permanent: true,
        }
    }
}

/// Size and modification time of a file as read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct FileStamp {
    pub size: u64,
    pub modified: Option<std::time::SystemTime>,
}

/// The largest file that can hold a capture within `limits`: its pixels as uncompressed f32
/// RGBA plus headers.
fn max_file_bytes(limits: &DecodeLimits) -> u64 {
    (limits.max_pixels as u64)
        .saturating_mul(16)
        .saturating_add(64 << 20)
}

/// Read a capture file's bytes safely: opened without blocking (a FIFO or device cannot hang
/// the reader), checked with `fstat` to be a regular file no larger than any capture within the
/// limits, and read through the same descriptor the checks used. When `root` is given, the
/// opened file must lie under it (a link swapped in after name resolution cannot leave it).
pub(crate) fn read_capture(
    root: Option<&Path>,
    path: &Path,
    limits: &DecodeLimits,
) -> Result<(Vec<u8>, FileStamp), AttemptError> {
    use std::io::Read;
    use std::os::unix::fs::{FileTypeExt, OpenOptionsExt};
    let mut file = std::fs::OpenOptions::new()
        .read(true)
        .custom_flags(libc::O_NONBLOCK | libc::O_NOCTTY)
        .open(path)
        .map_err(|e| AttemptError::retry(format!("cannot open: {e}"), None))?;
    if let Some(root) = root {
        if let (Some(real), Ok(real_root)) = (opened_path(&file), root.canonicalize()) {
            if !real.starts_with(&real_root) {
                return Err(AttemptError::permanent(
                    format!(
                        "refused: the file opened is {} (outside the capture root)",
                        real.display()
                    ),
                    None,
                ));
            }
        }
    }
    let before = file
        .metadata()
        .map_err(|e| AttemptError::retry(format!("cannot stat: {e}"), None))?;
    let ft = before.file_type();
    if !ft.is_file() {
        let what = if ft.is_fifo() {
            "a FIFO (named pipe)"
        } else if ft.is_dir() {
            "a directory"
        } else if ft.is_socket() {
            "a socket"
        } else if ft.is_char_device() || ft.is_block_device() {
            "a device"
        } else {
            "not a regular file"
        };
        return Err(AttemptError::permanent(
            format!("refused: {what}, not a regular capture file"),
            None,
        ));
    }
    let max_bytes = max_file_bytes(limits);
    if before.len() > max_bytes {
        return Err(AttemptError::permanent(
            format!(
                "file of {} bytes is larger than any capture within the decode limits ({max_bytes} bytes)",
                before.len()
            ),
            Some(before.len()),
        ));
    }
    let mut bytes = Vec::with_capacity(before.len() as usize);
    // one byte more than the limit at most: a file that grows past it is refused, not read on
    (&mut file)
        .take(max_bytes + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| AttemptError::retry(format!("cannot read: {e}"), Some(before.len())))?;
    let size = bytes.len() as u64;
    let after = file
        .metadata()
        .map_err(|e| AttemptError::retry(format!("cannot stat: {e}"), Some(size)))?;
    if after.len() != size || before.len() != size {
        return Err(AttemptError::retry(
            format!(
                "file is still growing ({} → {} bytes)",
                before.len(),
                after.len()
            ),
            Some(after.len()),
        ));
    }
    Ok((
        bytes,
        FileStamp {
            size,
            modified: after.modified().ok(),
        },
    ))
}

/// Read, decode and average one file once.
/// Average a decoded capture. A low-dynamic-range capture's code at its maximum reads 1.0
/// linear, which is where it clipped: its clip level is at most 1.
pub fn average_decoded(
    img: &crate::decode::DecodedImage,
    opts: &AverageOptions,
) -> Result<crate::measure::averaging::CaptureStats, crate::measure::averaging::AverageError> {
    if img.format.is_ldr() {
        let ldr = AverageOptions {
            clip_level: opts.clip_level.min(1.0),
            ..*opts
        };
        average(&img.view(), &ldr)
    } else {
        average(&img.view(), opts)
    }
}

pub fn measure_file(
    root: &Path,
    path: &Path,
    opts: &AverageOptions,
    limits: &DecodeLimits,
) -> Result<Outcome, AttemptError> {
    measure_file_stamped(root, path, opts, limits).map(|(o, _)| o)
}

fn measure_file_stamped(
    root: &Path,
    path: &Path,
    opts: &AverageOptions,
    limits: &DecodeLimits,
) -> Result<(Outcome, FileStamp), AttemptError> {
    let (bytes, stamp) = read_capture(Some(root), path, limits)?;
    let size = stamp.size;
    let img = decode(&bytes, limits).map_err(|e| AttemptError::retry(e.to_string(), Some(size)))?;
    let stats =
        average_decoded(&img, opts).map_err(|e| AttemptError::retry(e.to_string(), Some(size)))?;
    let sha256 = hex(&Sha256::digest(&bytes));
    Ok((
        Outcome::Ok {
            stats,
            width: img.width,
            height: img.height,
            size,
            sha256,
        },
        stamp,
    ))
}

/// The path of an open file as the kernel sees it (Linux: /proc/self/fd). None elsewhere.
fn opened_path(file: &std::fs::File) -> Option<PathBuf> {
    use std::os::fd::AsRawFd;
    std::fs::read_link(format!("/proc/self/fd/{}", file.as_raw_fd())).ok()
}

fn hex(b: &[u8]) -> String {
    b.iter().map(|x| format!("{x:02x}")).collect()
}

/// Whether a file read at `stamp` has stopped changing: last modified at least `settle` before
/// `now`, or seen with the same size and modification time at least `settle` ago (`earlier`:
/// the stamp and how long ago it was seen). A modification time in the future (a clock that
/// differs from the camera PC's) only counts through the second rule.
fn settled(
    stamp: &FileStamp,
    settle: Duration,
    now: std::time::SystemTime,
    earlier: Option<(FileStamp, Duration)>,
) -> bool {
    if settle.is_zero() {
        return true;
    }
    let old_enough = stamp
        .modified
        .and_then(|m| now.duration_since(m).ok())
        .is_some_and(|age| age >= settle);
    let unchanged = earlier.is_some_and(|(s, ago)| s == *stamp && ago >= settle);
    old_enough || unchanged
}

/// Ingest one announced capture with the retry policy; blocks the calling (worker) thread.
pub(crate) fn ingest(root: &Path, name: &str, spec: &IngestSpec, opts: &AverageOptions) -> Outcome {
    let path = match resolve(root, name) {
        Ok(p) => p,
        Err(e) => {
            return Outcome::Failed {
                error: e.to_string(),
            }
        }
    };
    let limits = decode_limits(spec);
    let start = Instant::now();
    // the config bounds give_up_s; the clamp keeps a hand-built spec from panicking here
    let give_up = Duration::from_secs_f64(spec.give_up_s.clamp(0.0, MAX_GIVE_UP_S));
    let settle = Duration::from_millis(spec.settle_ms);
    let mut delay = Duration::from_millis(spec.retry_first_ms.max(1));
    let mut last_size: Option<u64> = None;
    let mut same_size_failures = 0u32;
    let mut attempts = 0u32;
    let mut first_seen: Option<(FileStamp, Instant)> = None;
    loop {
        attempts += 1;
        // re-check the path each time: a link could be swapped in while we wait
        if let Err(e) = resolve(root, name) {
            return Outcome::Failed {
                error: e.to_string(),
            };
        }
        let elapsed = start.elapsed();
        let wait = match measure_file_stamped(root, &path, opts, &limits) {
            Ok((o, stamp)) => {
                let earlier = first_seen.map(|(s, at)| (s, at.elapsed()));
                if settled(&stamp, settle, std::time::SystemTime::now(), earlier) {
                    return o;
                }
                // past give-up, a file that decodes is refused only when it changed between two
                // looks; one that has stopped changing gets its settle interval
                let changed = first_seen.is_some_and(|(s, _)| s != stamp);
                if elapsed >= give_up && changed {
                    return Outcome::Failed {
                        error: format!(
                            "file kept changing for {:.1} s (last {} bytes); not accepted as a finished capture (after {attempts} attempts)",
                            spec.give_up_s, stamp.size
                        ),
                    };
                }
                if first_seen.is_none_or(|(s, _)| s != stamp) {
                    first_seen = Some((stamp, Instant::now()));
                }
                let seen_ago = first_seen.map(|(_, at)| at.elapsed()).unwrap_or_default();
                let until_settled = settle.saturating_sub(seen_ago);
                if elapsed < give_up {
                    until_settled.min(give_up - elapsed)
                } else {
                    until_settled
                }
            }
            Err(e) => {
                if e.permanent {
                    return Outcome::Failed { error: e.reason };
                }
                let exists = e.size.is_some();
                if exists && e.size == last_size {
                    same_size_failures += 1;
                } else {
                    same_size_failures = if exists { 1 } else { 0 };
                }
                last_size = e.size;
                let stable_bad = exists
                    && same_size_failures >= spec.stable_failures.max(1)
                    && !e.reason.contains("growing");
                if stable_bad || elapsed >= give_up {
                    return if exists {
                        Outcome::Failed {
                            error: format!("{} (after {attempts} attempts)", e.reason),
                        }
                    } else {
                        Outcome::Missing {
                            reason: format!(
                                "file not found after {:.1} s ({})",
                                spec.give_up_s, e.reason
                            ),
                        }
                    };
                }
                let d = delay;
                delay = (delay * 2).min(Duration::from_millis(spec.retry_max_ms.max(1)));
                d.min(give_up.saturating_sub(elapsed))
            }
        };
        std::thread::sleep(wait.max(Duration::from_millis(1)));
    }
}

/// A job for the pool.
#[derive(Debug, Clone)]
pub(crate) struct Job {
    pub idx: u64,
    pub file: String,
}

/// The bounded worker pool. Results go to `on_result` (called on the worker thread). Dropping
/// the pool closes its queue; workers finish the job they hold and end (they are not joined:
/// a decode in progress never holds up the daemon's exit).
pub(crate) struct Pool {
    tx: crossbeam_channel::Sender<Job>,
}

impl Pool {
    pub(crate) fn start<F>(
        root: PathBuf,
        spec: IngestSpec,
        opts: AverageOptions,
        on_result: F,
    ) -> Pool
    where
        F: Fn(u64, Outcome) + Send + Sync + 'static,
    {
        let (tx, rx) = crossbeam_channel::bounded::<Job>(spec.queue.max(1));
        let on_result = std::sync::Arc::new(on_result);
        for i in 0..spec.workers.max(1) {
            let rx = rx.clone();
            let (root, spec, on_result) = (root.clone(), spec.clone(), on_result.clone());
            let started = std::thread::Builder::new()
                .name(format!("ingest-{i}"))
                .spawn(move || {
                    while let Ok(job) = rx.recv() {
                        let outcome = ingest(&root, &job.file, &spec, &opts);
                        on_result(job.idx, outcome);
                    }
                });
            if let Err(e) = started {
                tracing::error!("cannot start ingest worker {i}: {e}");
            }
        }
        Pool { tx }
    }

    /// Queue a job; gives it back when the queue is full (backpressure).
    pub(crate) fn try_submit(&self, job: Job) -> Result<(), Job> {
        self.tx.try_send(job).map_err(|e| e.into_inner())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_checked() {
        let root = std::env::temp_dir();
        assert_eq!(resolve(&root, ""), Err(PathError::Empty));
        assert!(matches!(
            resolve(&root, "/etc/passwd"),
            Err(PathError::Absolute(_))
        ));
        assert!(matches!(
            resolve(&root, "a/../../etc/passwd"),
            Err(PathError::ParentDir(_))
        ));
        assert!(matches!(resolve(&root, ".."), Err(PathError::ParentDir(_))));
        assert!(resolve(&root, "demo/./cap_0.hdr").is_ok());
    }

    fn scratch(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("gw-ingest-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    fn valid_hdr() -> Vec<u8> {
        std::fs::read(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/tests/reference/images/valid/scale.hdr"
        ))
        .unwrap()
    }

    #[test]
    fn a_fifo_or_a_directory_is_refused_at_once_not_waited_on() {
        let root = scratch("fifo");
        let fifo = root.join("cap.hdr");
        let c = std::ffi::CString::new(fifo.to_str().unwrap()).unwrap();
        // SAFETY: a valid NUL-terminated path; mkfifo only creates a file system entry.
        assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
        std::fs::create_dir(root.join("dir.hdr")).unwrap();
        for (name, what) in [("cap.hdr", "FIFO"), ("dir.hdr", "directory")] {
            let r = measure_file(
                &root,
                &root.join(name),
                &AverageOptions::default(),
                &DecodeLimits::default(),
            );
            assert!(
                matches!(&r, Err(e) if e.permanent && e.reason.contains(what)),
                "{r:?}"
            );
            // the retry loop gives up at once on a permanent refusal (give_up_s would be a day)
            let spec = IngestSpec {
                give_up_s: MAX_GIVE_UP_S,
                ..IngestSpec::default()
            };
            let o = ingest(&root, name, &spec, &AverageOptions::default());
            assert!(
                matches!(&o, Outcome::Failed { error } if error.contains(what)),
                "{o:?}"
            );
        }
        std::fs::remove_dir_all(&root).ok();
    }

    #[test]
    fn settling_needs_an_old_enough_or_an_unchanged_stamp() {
        let now = std::time::SystemTime::UNIX_EPOCH + Duration::from_secs(1_000_000);
        let stamp = |size, ago_ms: i64| FileStamp {
            size,
            modified: Some(if ago_ms >= 0 {
                now - Duration::from_millis(ago_ms as u64)
            } else {
                now + Duration::from_millis((-ago_ms) as u64)
            }),
        };
        let settle = Duration::from_millis(500);
        assert!(settled(&stamp(10, 0), Duration::ZERO, now, None));
        assert!(settled(&stamp(10, 600), settle, now, None));
        assert!(!settled(&stamp(10, 100), settle, now, None));
        // a future modification time (another clock) only settles by being seen unchanged
        assert!(!settled(&stamp(10, -3_600_000), settle, now, None));
        let seen = Some((stamp(10, -3_600_000), Duration::from_millis(700)));
        assert!(settled(&stamp(10, -3_600_000), settle, now, seen));
        // seen before, but at another size: still changing
        let seen = Some((stamp(9, -3_600_000), Duration::from_millis(700)));
        assert!(!settled(&stamp(10, -3_600_000), settle, now, seen));
        let seen = Some((stamp(10, 100), Duration::from_millis(300)));
        assert!(!settled(&stamp(10, 100), settle, now, seen));
    }

    #[test]
    fn a_file_that_keeps_growing_is_never_accepted() {
        let root = scratch("grow");
        let path = root.join("cap.hdr");
        std::fs::write(&path, valid_hdr()).unwrap();
        // a writer that keeps appending to a file that already decodes
        let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
        let writer = {
            let (stop, path) = (stop.clone(), path.clone());
            std::thread::spawn(move || {
                use std::io::Write;
                let mut f = std::fs::OpenOptions::new()
                    .append(true)
                    .open(&path)
                    .unwrap();
                while !stop.load(std::sync::atomic::Ordering::Relaxed) {
                    f.write_all(&[0u8; 16]).unwrap();
                    std::thread::sleep(Duration::from_millis(20));
                }
            })
        };
        // settle (10 s) longer than give_up (1 s): only a file modified 10 s ago could pass
        let spec = IngestSpec {
            settle_ms: 10_000,
            give_up_s: 1.0,
            ..IngestSpec::default()
        };
        let o = ingest(&root, "cap.hdr", &spec, &AverageOptions::default());
        stop.store(true, std::sync::atomic::Ordering::Relaxed);
        writer.join().unwrap();
        assert!(
            matches!(&o, Outcome::Failed { error } if error.contains("kept changing")),
            "{o:?}"
        );
        // once it has stopped changing, it is accepted whole
        let size = std::fs::metadata(&path).unwrap().len();
        let spec = IngestSpec {
            settle_ms: 200,
            ..IngestSpec::default()
        };
        let o = ingest(&root, "cap.hdr", &spec, &AverageOptions::default());
        assert!(
            matches!(&o, Outcome::Ok { size: s, .. } if *s == size),
            "{o:?}"
        );
        std::fs::remove_dir_all(&root).ok();
    }

    #[test]
    fn a_finished_file_is_accepted_even_when_its_settle_interval_outlasts_give_up() {
        let root = scratch("settle-late");
        std::fs::write(root.join("cap.hdr"), valid_hdr()).unwrap();
        // just written, a settle interval longer than give-up: it waits out the interval
        let spec = IngestSpec {
            settle_ms: 300,
            give_up_s: 0.05,
            ..IngestSpec::default()
        };
        let o = ingest(&root, "cap.hdr", &spec, &AverageOptions::default());
        assert!(matches!(&o, Outcome::Ok { .. }), "{o:?}");
        std::fs::remove_dir_all(&root).ok();
    }

    #[test]
    fn links_leaving_the_root_are_refused() -> std::io::Result<()> {
        let base = std::env::temp_dir().join(format!("gw-resolve-{}", std::process::id()));
        let root = base.join("root");
        std::fs::create_dir_all(&root)?;
        std::fs::write(base.join("secret.hdr"), b"x")?;
        let _ = std::os::unix::fs::symlink(base.join("secret.hdr"), root.join("evil.hdr"));
        assert!(matches!(
            resolve(&root, "evil.hdr"),
            Err(PathError::OutsideRoot(_))
        ));
        // even when handed the link directly (a swap after `resolve`), the read refuses it
        let r = measure_file(
            &root,
            &root.join("evil.hdr"),
            &AverageOptions::default(),
            &DecodeLimits::default(),
        );
        assert!(
            matches!(&r, Err(e) if e.reason.contains("outside the capture root") && e.permanent),
            "{r:?}"
        );
        std::fs::remove_dir_all(&base).ok();
        Ok(())
    }
}
