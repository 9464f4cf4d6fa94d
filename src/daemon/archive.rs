//! Shell: the link for a files source (`[source] kind = "files"`). Instead of a serial port it
//! lists the capture folder, places the files with `archive::listing`, and lets
//! `archive::controller` speak the controller's side of the protocol to the engine, so the
//! journal, resume and replay are those of a protocol session.
//!
//! - A finished set (`goniowatch check`) is listed once and then ends (`STATUS state=done`).
//! - Watch mode (`goniowatch run` with a files source) lists the folder every `poll_ms` (and
//!   at once on a file-system event) and announces new captures as they appear; whether a file
//!   is finished is the ingestion's question, as for announced files. `archive::follow` keeps
//!   what was announced, so a failed or missing capture is checked again when its file changes,
//!   and a resumed session numbers on from where it stood. A folder moved away and made again
//!   is watched anew. It ends when every plan entry has been announced.
//! - Files placed on the same plan entry are settled by the listing's duplicate rule and
//!   reported to the engine (`Input::Duplicates`), which alarms them.
//!
//! The folder is only read.

use crate::archive::controller::ArchiveController;
use crate::archive::follow::Follower;
use crate::archive::listing::{self, ArchiveCapture, FileFact, Listing, SidecarRow, SkipReason};
use crate::archive::SourceSpec;
use crate::engine::Input;
use crate::measure::kinematics::Rig;
use crate::measure::plan::SamplingPlan;
use anyhow::{Context, Result};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Duration;
use tokio::sync::{mpsc, watch};

/// What the archive link needs.
pub(crate) struct ArchiveLink {
    pub(crate) root: PathBuf,
    pub(crate) spec: SourceSpec,
    pub(crate) plan: SamplingPlan,
    pub(crate) rig: Rig,
    /// The set is finished: list once and end.
    pub(crate) finished: bool,
    /// Watch mode resuming a session: its captures so far, in index order, and whether each
    /// is known to be usable (see `Engine::announced_captures`).
    pub(crate) prior: Vec<(u64, ArchiveCapture, Option<bool>)>,
    /// Watch mode: the ingestion's verdicts (`Some(sha256)` when the capture decoded).
    pub(crate) outcomes: Option<mpsc::UnboundedReceiver<(u64, Option<String>)>>,
}

/// What a folder listing found: the regular files under the root, and the entries that cannot
/// be captures (links, names that are not UTF-8) with why.
pub(crate) struct Found {
    pub(crate) files: Vec<FileFact>,
    pub(crate) refused: Vec<(String, SkipReason)>,
}

/// Every regular file under `root` (names relative to it, `/`-separated), leaving out names
/// that start with `.` (partial writes, editor files); links and names that are not UTF-8 are
/// refused with their reason, so that they appear among the skipped files.
pub(crate) fn list_files(root: &Path) -> Result<Found> {
    let mut out = Vec::new();
    let mut refused = Vec::new();
    let walk = walkdir::WalkDir::new(root)
        .follow_links(false)
        .sort_by_file_name()
        .into_iter()
        .filter_entry(|e| e.depth() == 0 || !e.file_name().to_string_lossy().starts_with('.'));
    for e in walk {
        let e = match e {
            Ok(e) => e,
            // the folder itself must be readable; a sub-folder that vanished or is unreadable
            // is left out (its files are reported as missing if they were expected)
            Err(err) if err.depth() == 0 => {
                return Err(anyhow::anyhow!("cannot list {}: {err}", root.display()))
            }
            Err(err) => {
                tracing::warn!("files source: {err}");
                continue;
            }
        };
        let Ok(rel) = e.path().strip_prefix(root) else {
            continue;
        };
        // (the root itself may be a link to the capture folder: it is followed)
        if e.depth() > 0 && e.path_is_symlink() {
            refused.push((rel.to_string_lossy().replace('\\', "/"), SkipReason::Link));
            continue;
        }
        if !e.file_type().is_file() {
            continue;
        }
        let Some(name) = rel.to_str() else {
            refused.push((
                rel.to_string_lossy().replace('\\', "/"),
                SkipReason::NameNotUtf8,
            ));
            continue;
        };
        let meta = e.metadata().ok();
        let mtime_s = meta
            .as_ref()
            .and_then(|m| m.modified().ok())
            .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
            .map(|d| d.as_secs_f64());
        out.push(FileFact {
            name: name.replace('\\', "/"),
            mtime_s,
            size: meta.map(|m| m.len()),
        });
    }
    out.sort_by(|a, b| a.name.cmp(&b.name));
    Ok(Found {
        files: out,
        refused,
    })
}

/// Read the sidecar named in `spec`, if any.
fn read_sidecar(root: &Path, spec: &SourceSpec) -> Result<Option<Vec<SidecarRow>>> {
    let Some(rel) = &spec.sidecar else {
        return Ok(None);
    };
    let path = root.join(rel);
    let text = std::fs::read_to_string(&path)
        .with_context(|| format!("cannot read the sidecar {}", path.display()))?;
    let csv = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("csv"));
    let rows = listing::parse_sidecar(&text, csv)
        .with_context(|| format!("sidecar {}", path.display()))?;
    Ok(Some(rows))
}

/// List and place the capture folder's files.
pub(crate) fn place(link: &ArchiveLink) -> Result<Listing> {
    Ok(place_with_prints(link)?.0)
}

/// Each listed file's size and modification time, by name.
type Prints = BTreeMap<String, (u64, Option<f64>)>;

/// List and place the capture folder's files; also each file's fingerprint.
fn place_with_prints(link: &ArchiveLink) -> Result<(Listing, Prints)> {
    let found = list_files(&link.root)?;
    let prints: Prints = found
        .files
        .iter()
        .filter_map(|f| f.size.map(|s| (f.name.clone(), (s, f.mtime_s))))
        .collect();
    let sidecar = read_sidecar(&link.root, &link.spec)?;
    let mut listing = listing::build(
        &found.files,
        sidecar.as_deref(),
        &link.spec,
        &link.plan,
        &link.rig,
    )?;
    listing.skipped.extend(found.refused);
    listing.skipped.sort_by(|a, b| a.0.cmp(&b.0));
    Ok((listing, prints))
}

/// The SHA-256 of a capture file's bytes now (watch mode asks it of a checked file that
/// changed, to tell a rewrite from a touch).
fn content_of(root: &Path, name: &str) -> Option<String> {
    use sha2::{Digest, Sha256};
    let path = super::ingest::resolve(root, name).ok()?;
    let bytes = std::fs::read(path).ok()?;
    Some(
        Sha256::digest(&bytes)
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect(),
    )
}

/// What tells one folder from another made at the same path (device and inode).
fn identity(root: &Path) -> Option<(u64, u64)> {
    use std::os::unix::fs::MetadataExt;
    std::fs::metadata(root).ok().map(|m| (m.dev(), m.ino()))
}

/// Place the files of `root` as a session with `config` would (for `check` to refuse a folder
/// with no capture before a session folder is made).
pub(crate) fn preflight(root: &Path, config: &crate::config::Config) -> Result<Listing> {
    place(&ArchiveLink {
        root: root.to_path_buf(),
        spec: config.source.clone(),
        plan: crate::setup::plan(config)?,
        rig: Rig::new(config.rig.clone())?,
        finished: true,
        prior: Vec::new(),
        outcomes: None,
    })
}

/// Tell the operator what was placed and what was not (the first `show` skipped files).
pub(crate) fn describe(listing: &Listing, show: usize) -> String {
    let mut s = format!("goniowatch: files source: {}", listing.describe());
    for (name, why) in listing.skipped.iter().take(show) {
        s.push_str(&format!("\n  skipped {name}: {why}"));
    }
    if listing.skipped.len() > show {
        s.push_str(&format!("\n  … and {} more", listing.skipped.len() - show));
    }
    s
}

/// How many files not placed one `Input::Skipped` names (it is one journal line); all are counted.
const MAX_SKIPPED_NAMED: usize = 1000;

/// The engine input for a listing's files not placed.
fn skipped_input(skipped: &[(String, SkipReason)]) -> Input {
    let mut counts: BTreeMap<String, u64> = BTreeMap::new();
    for (_, why) in skipped {
        *counts.entry(why.kind().to_string()).or_default() += 1;
    }
    Input::Skipped {
        files: skipped.iter().take(MAX_SKIPPED_NAMED).cloned().collect(),
        counts,
    }
}

/// After a file-system event, how long to wait for the burst around it before listing.
const WAKE_SETTLE: Duration = Duration::from_millis(50);

/// Watch `root` recursively; every event sends a wake-up. None (polling only) when the file
/// system cannot be watched.
fn watch_folder(
    root: &Path,
    wake: mpsc::UnboundedSender<()>,
) -> Option<notify::RecommendedWatcher> {
    use notify::Watcher;
    let handler = move |event: notify::Result<notify::Event>| {
        if event.is_ok() {
            let _ = wake.send(());
        }
    };
    match notify::recommended_watcher(handler) {
        Ok(mut w) => match w.watch(root, notify::RecursiveMode::Recursive) {
            Ok(()) => Some(w),
            Err(e) => {
                tracing::warn!(
                    "cannot watch {} for changes ({e}); listing it every source.poll_ms instead",
                    root.display()
                );
                None
            }
        },
        Err(e) => {
            tracing::warn!("no file-system watcher ({e}); listing every source.poll_ms instead");
            None
        }
    }
}

fn flush(ctl: &mut ArchiveController, events: &mpsc::UnboundedSender<Input>) -> bool {
    while let Some(line) = ctl.poll_line() {
        if events.send(Input::Rx { line }).is_err() {
            return false;
        }
    }
    true
}

/// How often watch mode looks whether the folder was replaced (a cheap `stat`), whatever
/// `poll_ms` is.
const IDENTITY_CHECK: Duration = Duration::from_secs(1);

/// Run the link until `stop` turns true: inputs to `events`, the engine's lines from `lines`.
pub(crate) async fn run(
    mut link: ArchiveLink,
    events: mpsc::UnboundedSender<Input>,
    mut lines: mpsc::UnboundedReceiver<String>,
    mut stop: watch::Receiver<bool>,
) {
    let planned = link.plan.capture_count();
    let session = link
        .root
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "files".into());
    let mut ctl = ArchiveController::new(&session, planned);
    if events.send(Input::Connected).is_err() {
        return;
    }
    ctl.handle_connect();
    let mut follower = Follower::new();
    for (idx, c, usable) in std::mem::take(&mut link.prior) {
        if !follower.handle_prior(idx, &c, usable) {
            tracing::warn!("files source: capture {idx} of the session breaks the numbering; captures from it on are placed anew");
            break;
        }
        ctl.handle_capture(c);
    }
    let mut outcomes = link.outcomes.take();
    let mut ended = false;
    let mut said = false;
    let mut last_error: Option<String> = None;
    let poll = Duration::from_millis(link.spec.poll_ms.max(10));
    // watch mode: a change in the folder lists it at once (inotify); the listing every
    // `poll_ms` stays as the fallback for file systems that send no events (network shares)
    let (wake_tx, mut wake) = mpsc::unbounded_channel::<()>();
    let watching = !link.finished && link.spec.notify;
    // held for its lifetime: dropping it ends the watch
    let mut _watcher = None;
    let mut watched: Option<(u64, u64)> = None;
    let mut watch_failed = false;
    let mut seen_folder: Option<(u64, u64)> = None;
    let link = std::sync::Arc::new(link);
    let mut tick = tokio::time::interval(poll);
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let mut look = tokio::time::interval(IDENTITY_CHECK.min(poll));
    look.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    loop {
        tokio::select! {
            _ = tick.tick(), if !ended => {
                // (again) until the folder exists and can be watched; a folder replaced since
                // it was watched is watched anew
                let now = identity(&link.root);
                if watching && now.is_some() && now != watched && !watch_failed {
                    if watched.is_some() {
                        tracing::warn!("files source: {} was replaced; watching the new folder", link.root.display());
                        eprintln!("goniowatch: files source: {} was replaced by another folder; watching the new one", link.root.display());
                    }
                    _watcher = watch_folder(&link.root, wake_tx.clone());
                    watch_failed = _watcher.is_none();
                    watched = if watch_failed { None } else { now };
                } else if !watching && now.is_some() && seen_folder.is_some() && now != seen_folder {
                    eprintln!("goniowatch: files source: {} was replaced by another folder; listing the new one", link.root.display());
                }
                if now.is_some() {
                    seen_folder = now;
                }
                let l = link.clone();
                match tokio::task::spawn_blocking(move || place_with_prints(&l)).await {
                    Ok(Ok((listing, prints))) => {
                        last_error = None;
                        if !said && (link.finished || !listing.captures.is_empty()) {
                            eprintln!("{}", describe(&listing, 20));
                            said = true;
                        }
                        let root = link.root.clone();
                        let step = if link.finished {
                            // a finished set is placed once, as listed (nothing to check again)
                            follower.handle_listing(&listing, &prints, &mut |_| None)
                        } else {
                            follower.handle_listing(&listing, &prints, &mut |name| content_of(&root, name))
                        };
                        if step.rechecks > 0 {
                            eprintln!("goniowatch: files source: {} capture file(s) changed after a failed, missing or superseded check; checking them again", step.rechecks);
                        }
                        // before the captures, so the engine holds each step when it checks its capture
                        for (idx, back) in step.steps_back {
                            if events.send(Input::TimeSteppedBack { idx, step: back }).is_err() {
                                return;
                            }
                        }
                        for (_, c) in step.announce {
                            ctl.handle_capture(c);
                        }
                        if !flush(&mut ctl, &events) {
                            return;
                        }
                        if !step.duplicates.is_empty()
                            && events.send(Input::Duplicates { groups: step.duplicates }).is_err()
                        {
                            return;
                        }
                        if link.finished || follower.complete(planned) {
                            // the final listing's files not placed, for the summary and the report
                            if events.send(skipped_input(&listing.skipped)).is_err() {
                                return;
                            }
                            ctl.handle_end();
                            ended = true;
                        }
                    }
                    Ok(Err(e)) => {
                        // a folder that is not there yet is looked for every second
                        tick.reset_after(poll.min(Duration::from_secs(1)));
                        let msg = format!("{e:#}");
                        if last_error.as_ref() != Some(&msg) {
                            tracing::warn!("files source: {msg}; listing again");
                            eprintln!("goniowatch: files source: {msg}; listing again");
                            last_error = Some(msg);
                        }
                    }
                    Err(e) => tracing::warn!("files source: listing failed: {e}"),
                }
            }
            _ = look.tick(), if !ended && watching => {
                // a folder moved away and made again sends no event to the old watch
                let now = identity(&link.root);
                if now.is_some() && watched.is_some() && now != watched {
                    tick.reset_immediately();
                }
            }
            Some((idx, checked)) = async {
                match outcomes.as_mut() {
                    Some(rx) => rx.recv().await,
                    None => std::future::pending().await,
                }
            } => follower.handle_outcome(idx, checked),
            line = lines.recv() => match line {
                Some(line) => ctl.handle_line(&line),
                None => return,
            },
            Some(()) = wake.recv(), if !ended => {
                // let a burst of events settle, then list on the next turn
                tokio::time::sleep(WAKE_SETTLE).await;
                while wake.try_recv().is_ok() {}
                tick.reset_immediately();
            }
            _ = stop.changed() => return,
        }
        // answer everything the engine has sent so far
        while let Ok(line) = lines.try_recv() {
            ctl.handle_line(&line);
        }
        if !flush(&mut ctl, &events) {
            return;
        }
    }
}
