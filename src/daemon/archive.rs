//! Shell: the link for a files source (`[source] kind = "files"`). Instead of a serial port it
//! lists the capture folder, places the files with `archive::listing`, and lets
//! `archive::controller` speak the controller's side of the protocol to the engine, so the
//! journal, resume and replay are those of a protocol session.
//!
//! - A finished set (`goniowatch check`) is listed once and then ends (`STATUS state=done`).
//! - Watch mode (`goniowatch run` with a files source) lists the folder every `poll_ms` and
//!   announces new captures as they appear; whether a file is finished is the ingestion's
//!   question, as for announced files. It ends when every plan entry has been announced.
//!
//! The folder is only read.

use crate::archive::controller::ArchiveController;
use crate::archive::listing::{self, FileFact, Listing, SidecarRow, SkipReason};
use crate::archive::SourceSpec;
use crate::engine::Input;
use crate::measure::kinematics::Rig;
use crate::measure::plan::SamplingPlan;
use anyhow::{Context, Result};
use std::collections::BTreeSet;
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
        let mtime_s = e
            .metadata()
            .ok()
            .and_then(|m| m.modified().ok())
            .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
            .map(|d| d.as_secs_f64());
        out.push(FileFact {
            name: name.replace('\\', "/"),
            mtime_s,
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
    let found = list_files(&link.root)?;
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
    Ok(listing)
}

/// Place the files of `root` as a session with `config` would (for `check` to refuse a folder
/// with no capture before a session folder is made).
pub fn preflight(root: &Path, config: &crate::config::Config) -> Result<Listing> {
    place(&ArchiveLink {
        root: root.to_path_buf(),
        spec: config.source.clone(),
        plan: config.plan()?,
        rig: Rig::new(config.rig.clone())?,
        finished: true,
    })
}

/// Tell the operator what was placed and what was not (the first `show` skipped files).
pub fn describe(listing: &Listing, show: usize) -> String {
    let mut s = format!("goniowatch: files source: {}", listing.describe());
    for (name, why) in listing.skipped.iter().take(show) {
        s.push_str(&format!("\n  skipped {name}: {why}"));
    }
    if listing.skipped.len() > show {
        s.push_str(&format!("\n  … and {} more", listing.skipped.len() - show));
    }
    s
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

/// Run the link until `stop` turns true: inputs to `events`, the engine's lines from `lines`.
pub(crate) async fn run(
    link: ArchiveLink,
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
    let mut announced: BTreeSet<String> = BTreeSet::new();
    let mut entries: BTreeSet<usize> = BTreeSet::new();
    let mut ended = false;
    let mut said = false;
    let mut last_error: Option<String> = None;
    let poll = Duration::from_millis(link.spec.poll_ms.max(10));
    // watch mode: a change in the folder lists it at once (inotify); the listing every
    // `poll_ms` stays as the fallback for file systems that send no events (network shares)
    let (wake_tx, mut wake) = mpsc::unbounded_channel::<()>();
    let watching = !link.finished && link.spec.notify;
    let mut watcher = None;
    let mut watch_failed = false;
    let link = std::sync::Arc::new(link);
    let mut tick = tokio::time::interval(poll);
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    loop {
        tokio::select! {
            _ = tick.tick(), if !ended => {
                // (again) until the folder exists and can be watched
                if watching && watcher.is_none() && !watch_failed && link.root.is_dir() {
                    watcher = watch_folder(&link.root, wake_tx.clone());
                    watch_failed = watcher.is_none();
                }
                let l = link.clone();
                match tokio::task::spawn_blocking(move || place(&l)).await {
                    Ok(Ok(listing)) => {
                        last_error = None;
                        if !said && (link.finished || !listing.captures.is_empty()) {
                            eprintln!("{}", describe(&listing, 20));
                            said = true;
                        }
                        for c in listing.captures {
                            if !entries.contains(&c.entry) && announced.insert(c.file.clone()) {
                                entries.insert(c.entry);
                                ctl.handle_capture(c);
                            }
                        }
                        if link.finished || entries.len() >= planned {
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
                            last_error = Some(msg);
                        }
                    }
                    Err(e) => tracing::warn!("files source: listing failed: {e}"),
                }
            }
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
