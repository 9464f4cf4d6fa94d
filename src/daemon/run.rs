//! Shell: `goniowatch run`, the live daemon.
//!
//! One task owns the engine and the session files. Everything else sends it `Input`s: the link
//! task (lines, connect/disconnect), the ingestion workers (outcomes). Each input is journaled
//! before the engine sees it; the engine's outputs are carried out in order: lines go to the
//! link, captures to the pool, records to the result files, alarms to the sinks.

use super::ingest::{Job, Pool};
use super::sinks::{log_alarm, run_hook};
use super::status::{Published, StatusModel};
use crate::checks::Outcome;
use crate::engine::{Engine, Input, Output, Summary};
use crate::session::folder::{Results, SessionLock};
use crate::session::journal::{now_ms, JournalEntry, JournalItem, JsonlFile};
use crate::session::recovery::{recover, ConfigGiven, Session};
use anyhow::{Context, Result};
use std::collections::{BTreeSet, VecDeque};
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};
use tokio::sync::{mpsc, watch};

/// After this long without a line from the controller, ask where it stands (`Input::Idle`).
const IDLE_AFTER: Duration = Duration::from_secs(5);

pub(crate) struct RunOptions {
    pub session_dir: PathBuf,
    pub config: Option<PathBuf>,
    /// A config given as text, and the name session.json records for it (used when `config`
    /// is not given).
    pub config_text: Option<(String, PathBuf)>,
    pub port: Option<PathBuf>,
    pub capture_root: Option<PathBuf>,
    /// Stay attached after the controller reports `done` (default: exit once all is checked).
    pub keep_running: bool,
    /// Draw a progress bar (when stderr is a terminal).
    pub progress: bool,
    /// Serve the status page here (`--http`).
    pub http: Option<std::net::SocketAddr>,
    /// With a files source: the capture folder is a finished set (`check`), listed once,
    /// rather than followed as it is written.
    pub finished_set: bool,
    /// Decoding threads for this run instead of the config's `ingest.workers` (`check` uses
    /// every core).
    pub workers: Option<usize>,
}

/// The most unannounced file names recorded at the end of a run.
const MAX_UNANNOUNCED: usize = 1000;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum RunEnd {
    Finished { critical: bool },
    Signal(i32),
}

struct Live {
    engine: Engine,
    journal: JsonlFile,
    results: Results,
    pool: Pool,
    pending_jobs: VecDeque<Job>,
    link_tx: mpsc::UnboundedSender<String>,
    hook: Vec<String>,
    bar: Option<indicatif::ProgressBar>,
    capture_root: PathBuf,
    /// Files in the capture folder that are not captures by definition (a files source's
    /// sidecar), left out of the unannounced files.
    not_captures: BTreeSet<String>,
    /// The captures are a files source's (its listing accounts for every file).
    files_source: bool,
    finished: bool,
    last_plain_report: Instant,
    hooks: Vec<tokio::task::JoinHandle<()>>,
    status: Option<StatusFeed>,
}

/// The status page's model and the channel its readers take snapshots from.
struct StatusFeed {
    model: StatusModel,
    tx: watch::Sender<Option<std::sync::Arc<Published>>>,
    started: Instant,
    last: Option<Instant>,
}

impl StatusFeed {
    /// Publish at most every 250 ms unless forced; never waits for a reader.
    fn publish(&mut self, summary: &Summary, force: bool) {
        if !force
            && self
                .last
                .is_some_and(|l| l.elapsed() < Duration::from_millis(250))
        {
            return;
        }
        self.last = Some(Instant::now());
        let snap = self
            .model
            .snapshot(summary, self.started.elapsed().as_secs_f64());
        self.tx
            .send_replace(Some(std::sync::Arc::new(Published::new(snap))));
    }
}

impl Live {
    fn submit_pending(&mut self) {
        while let Some(job) = self.pending_jobs.pop_front() {
            if let Err(job) = self.pool.try_submit(job) {
                self.pending_jobs.push_front(job);
                break;
            }
        }
    }

    fn process(&mut self, input: Input) -> Result<()> {
        let is_outcome = matches!(input, Input::Outcome { .. });
        self.journal.write_entry(&JournalEntry {
            wall_ms: now_ms(),
            item: JournalItem::In(input.clone()),
        })?;
        let outputs = self.engine.handle(&input);
        self.carry_out(outputs)?;
        if is_outcome {
            self.results.sync()?;
            self.journal.sync()?;
            self.submit_pending();
            self.update_progress();
        }
        Ok(())
    }

    fn carry_out(&mut self, outputs: Vec<Output>) -> Result<()> {
        for o in outputs {
            if let Some(s) = &mut self.status {
                s.model.record(&o);
            }
            match &o {
                Output::Send(line) => {
                    self.journal.write_entry(&JournalEntry {
                        wall_ms: now_ms(),
                        item: JournalItem::Out(line.clone()),
                    })?;
                    let _ = self.link_tx.send(line.clone());
                }
                Output::Ingest { idx, file } => {
                    self.pending_jobs.push_back(Job {
                        idx: *idx,
                        file: file.clone(),
                    });
                    self.submit_pending();
                }
                Output::Finished => self.finished = true,
                Output::ProbePose(p) => tracing::info!(
                    "drift probes: plan entry {} (θi {:.0}°, θo {:.0}°, {:.0}° from the mirror direction, {:.2} %/° to a pose error)",
                    p.entry,
                    p.theta_i_deg,
                    p.theta_o_deg,
                    p.specular_distance_deg,
                    p.sensitivity_pct_per_deg
                ),
                Output::SentinelPose(p) => tracing::info!(
                    "joint-3 sentinel: plan entry {} (θo {:.0}°, φo {:.0}°, {:+.2} %/° of joint 3), probed after each drift probe",
                    p.entry,
                    p.theta_o_deg,
                    p.phi_o_deg,
                    p.sensitivity_pct_per_deg
                ),
                Output::Alarm(a) => {
                    log_alarm(a, self.bar.as_ref(), false);
                    self.hooks.retain(|h| !h.is_finished());
                    self.hooks.extend(run_hook(&self.hook, a, false));
                    self.results.record(&o)?;
                }
                _ => self.results.record(&o)?,
            }
        }
        Ok(())
    }

    fn publish_status(&mut self, force: bool) {
        if let Some(s) = &mut self.status {
            s.publish(&self.engine.summary(), force);
        }
    }

    fn update_progress(&mut self) {
        self.publish_status(false);
        let done = self.engine.checked_through();
        let total = self.engine.captures_planned();
        let t2 = self.engine.table2();
        let msg = format!(
            "alarms {}  pairs {}  mean ΔE*ab {:.2}  ΔE00 {:.2}",
            self.engine.alarm_count(),
            t2.pairs,
            t2.de76,
            t2.de2000
        );
        match &self.bar {
            Some(b) if !b.is_hidden() => {
                b.set_length(total);
                b.set_position(done);
                b.set_message(msg);
            }
            _ => {
                if self.last_plain_report.elapsed() >= Duration::from_secs(10) || done == total {
                    self.last_plain_report = Instant::now();
                    eprintln!("goniowatch: checked {done}/{total}  {msg}");
                }
            }
        }
    }

    /// Files in the capture folders of announced captures that no CAPTURE line named.
    fn unannounced(&self) -> Vec<String> {
        unannounced(&self.engine, &self.capture_root, &self.not_captures)
    }
}

/// Files in the capture folders of announced captures that no CAPTURE line named, at most
/// `MAX_UNANNOUNCED` of them (the list is one journal line). `not_captures`: files that are not
/// captures by definition (a files source's sidecar).
pub(crate) fn unannounced(
    engine: &Engine,
    capture_root: &Path,
    not_captures: &BTreeSet<String>,
) -> Vec<String> {
    let announced: BTreeSet<&str> = engine.announced_files().collect();
    let mut dirs = BTreeSet::new();
    // only names the ingestion accepts: an absolute or climbing name must not steer the scan
    for f in announced
        .iter()
        .filter(|f| super::ingest::resolve(capture_root, f).is_ok())
    {
        if let Some(parent) = Path::new(f).parent() {
            dirs.insert(parent.to_path_buf());
        }
    }
    let mut out = Vec::new();
    for d in dirs {
        let Ok(rd) = std::fs::read_dir(capture_root.join(&d)) else {
            continue;
        };
        let mut names: Vec<String> = rd
            .filter_map(|e| e.ok())
            .filter(|e| e.file_type().map(|t| t.is_file()).unwrap_or(false))
            .filter_map(|e| e.file_name().to_str().map(str::to_string))
            .filter(|n| !n.starts_with('.'))
            .map(|n| d.join(n).to_string_lossy().into_owned())
            .filter(|n| !announced.contains(n.as_str()) && !not_captures.contains(n))
            .collect();
        names.sort();
        out.extend(names);
    }
    if out.len() > MAX_UNANNOUNCED {
        tracing::warn!(
            "{} unannounced files in the capture folder; the first {MAX_UNANNOUNCED} are recorded",
            out.len()
        );
        out.truncate(MAX_UNANNOUNCED);
    }
    out
}

/// Run beside the rig until the run is done (or a signal): start, then step on every input and
/// tick, then shut down.
pub(crate) async fn run(opts: RunOptions) -> Result<(RunEnd, Summary)> {
    // the status address is checked and bound before the session folder is touched
    let listener = match opts.http {
        None => None,
        Some(addr) => Some(bind_status(&opts, addr).await?),
    };
    let watch_text = match &opts.config {
        Some(p) => watch_scale(p, &opts),
        None => None,
    };
    let given = match (&opts.config, &opts.config_text) {
        (Some(p), _) => Some(match &watch_text {
            Some(text) => ConfigGiven::Text { text, source: p },
            None => ConfigGiven::File(p),
        }),
        (None, Some((text, source))) => Some(ConfigGiven::Text { text, source }),
        (None, None) => None,
    };
    let session = Session::open_or_create_given(
        &opts.session_dir,
        given,
        opts.port.as_deref(),
        opts.capture_root.as_deref(),
    )?;
    let _lock = SessionLock::acquire(&session.dir)?;
    let (mut live, mut ch) = start(&session, &opts, listener).await?;
    let end = steps(&mut live, &mut ch, opts.keep_running).await?;
    let summary = shutdown(live, ch).await?;
    Ok((end, summary))
}

/// Watch mode with a config that leaves `[colour] rgb_scale` unset, starting a new session:
/// the config's text with the white taken from the captures already in the folder (printed).
/// `None` for anything else (the config is then read as it is, and its errors reported there).
fn watch_scale(config: &std::path::Path, opts: &RunOptions) -> Option<String> {
    if opts.finished_set || opts.session_dir.join("config.toml").exists() {
        return None;
    }
    let text = std::fs::read_to_string(config).ok()?;
    let cfg = crate::config::Config::from_toml_str(&text).ok()?;
    if cfg.source.kind != crate::archive::SourceKind::Files || cfg.colour.rgb_scale.is_some() {
        return None;
    }
    let root = opts.capture_root.as_deref()?;
    let found = super::archive::preflight(root, &cfg)
        .ok()
        .and_then(|listing| super::scale::from_captures(root, &listing.captures, &cfg));
    match found {
        Some(found) => {
            eprintln!("{}", found.describe());
            super::scale::with_scale(&text, found.rgb_scale).ok()
        }
        None => {
            eprintln!(
                "goniowatch: [colour] rgb_scale is not set and the capture folder holds fewer than {} captures with a positive luminance: the files' values are taken as they are (rgb_scale = 1), so the dark level and L*a*b* assume a white of Y = 100 on the files' scale. Set [colour] rgb_scale, or start watch mode once the folder holds captures",
                crate::measure::stats::WHITE_MIN_CAPTURES
            );
            None
        }
    }
}

/// The channels between the run loop and its tasks.
struct Channels {
    events: mpsc::UnboundedReceiver<Input>,
    stop: watch::Sender<bool>,
    link: tokio::task::JoinHandle<()>,
    /// The session had finished before this start: nothing is left to wait for.
    already_finished: bool,
}

/// Check a non-loopback status address against the config (before the session is opened, so
/// the stored config is read directly) and bind it.
async fn bind_status(
    opts: &RunOptions,
    addr: std::net::SocketAddr,
) -> Result<tokio::net::TcpListener> {
    if !addr.ip().to_canonical().is_loopback() {
        let stored = opts.session_dir.join("config.toml");
        // the stored config is read as a resume reads it (runtime keys clamped, not refused)
        let allow = if stored.exists() {
            let text = std::fs::read_to_string(&stored)
                .with_context(|| format!("reading {}", stored.display()))?;
            crate::session::folder::parse_stored_config(&stored, &text)?
                .http
                .allow_remote
        } else {
            match &opts.config {
                Some(p) => crate::config::Config::load(p)?.0.http.allow_remote,
                None => false,
            }
        };
        super::http::check_address(&addr, allow)?;
    }
    super::http::bind(addr).await
}

fn progress_bar(opts: &RunOptions, captures: u64) -> Option<indicatif::ProgressBar> {
    if !(opts.progress && std::io::stderr().is_terminal()) {
        return None;
    }
    let b = indicatif::ProgressBar::new(captures);
    b.set_style(
        indicatif::ProgressStyle::with_template(
            "{spinner} [{elapsed_precise}] {bar:30} {pos}/{len} {per_sec} ETA {eta} {msg}",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    b.enable_steady_tick(Duration::from_millis(250));
    Some(b)
}

/// Recover the session (on a resume), open its files, start the ingestion pool, the status
/// page and the link, and report the alarm states that hold now.
async fn start(
    session: &Session,
    opts: &RunOptions,
    listener: Option<tokio::net::TcpListener>,
) -> Result<(Live, Channels)> {
    let cfg = &session.config;
    let bar = progress_bar(opts, crate::setup::plan(cfg)?.capture_count() as u64);
    // recover: rebuild the results from the journal, then note the restart
    let engine = if session.resumed {
        let (e, n) = recover(session).context("cannot recover the session from its journal")?;
        eprintln!(
            "goniowatch: resuming {} ({n} journaled inputs, {} captures already checked)",
            session.dir.display(),
            e.checked_through()
        );
        e
    } else {
        crate::engine::Engine::from_config(cfg)?
    };
    // the probe cadence and the run time it costs, before the run
    if cfg.source.kind == crate::archive::SourceKind::Protocol
        || cfg.probes.every == crate::detect::probes::ProbeEvery::Auto
    {
        let cadence = crate::setup::probe_cadence(cfg)?.describe();
        tracing::info!("{cadence}");
        eprintln!("goniowatch: {cadence}");
    }
    // what no detector of this session looks at, said before the run, not after it
    for b in engine.summary().observability.blind {
        tracing::warn!(what = %b.what, "not observable in this session: {}; {}", b.why, b.remedy);
        eprintln!(
            "goniowatch: not observable in this session: {} ({}); to observe it: {}",
            b.what, b.why, b.remedy
        );
    }
    let results = Results::open(&session.dir, !session.resumed)?;
    let journal = JsonlFile::append(&session.dir.join("journal.jsonl"))?;

    let (ev_tx, ev_rx) = mpsc::unbounded_channel::<Input>();
    let (link_tx, link_rx) = mpsc::unbounded_channel::<String>();
    let (stop_tx, stop_rx) = watch::channel(false);
    let outcome_tx = ev_tx.clone();
    // watch mode follows the verdicts, to check a failed capture again when its file changes
    let watch_files = cfg.source.kind == crate::archive::SourceKind::Files && !opts.finished_set;
    let (verdict_tx, verdict_rx) = mpsc::unbounded_channel::<(u64, Option<String>)>();
    let verdict_tx = watch_files.then_some(verdict_tx);
    let mut ingest = cfg.ingest.clone();
    if opts.finished_set {
        // a finished set gets no more files: a listed capture that is not there (a sidecar row
        // without its file) is missing now, not after `give_up_s`
        ingest.give_up_s = 0.0;
    }
    if let Some(w) = opts.workers {
        ingest.workers = w.clamp(1, 64);
        ingest.queue = ingest.queue.max(2 * ingest.workers);
    }
    let pool = Pool::start(
        session.info.capture_root.clone(),
        ingest,
        cfg.capture,
        move |idx, outcome| {
            if let Some(tx) = &verdict_tx {
                let checked = match &outcome {
                    Outcome::Ok { sha256, .. } => Some(sha256.clone()),
                    Outcome::Failed { .. } | Outcome::Missing { .. } => None,
                };
                let _ = tx.send((idx, checked));
            }
            let _ = outcome_tx.send(Input::Outcome { idx, outcome });
        },
    );
    let mut live = Live {
        engine,
        journal,
        results,
        pool,
        pending_jobs: VecDeque::new(),
        link_tx,
        hook: cfg.alarms.hook.clone(),
        bar,
        capture_root: session.info.capture_root.clone(),
        not_captures: match (&cfg.source.kind, &cfg.source.sidecar) {
            (crate::archive::SourceKind::Files, Some(p)) => {
                BTreeSet::from([p.to_string_lossy().replace('\\', "/")])
            }
            _ => BTreeSet::new(),
        },
        files_source: cfg.source.kind == crate::archive::SourceKind::Files,
        finished: false,
        last_plain_report: Instant::now(),
        hooks: Vec::new(),
        status: None,
    };
    if let Some(listener) = listener {
        let mut model = StatusModel::new(&crate::setup::plan(cfg)?, cfg.checks.dark_y);
        if session.resumed {
            model.load(&session.dir);
        }
        let (tx, rx) = watch::channel(None);
        let (local, _server) = super::http::serve(listener, rx).await?;
        eprintln!("goniowatch: status page on http://{local}/");
        live.status = Some(StatusFeed {
            model,
            tx,
            started: Instant::now(),
            last: None,
        });
        live.publish_status(true);
    }
    if session.resumed {
        live.process(Input::Restart)?;
        for (idx, file) in live.engine.pending_ingest() {
            live.pending_jobs.push_back(Job { idx, file });
        }
        live.submit_pending();
    }
    // a session that had already finished (and reported its unannounced files) has nothing
    // left to wait for
    let already_finished = live.engine.is_finished();
    // alarm states are evaluated on start and resume, not only on transitions
    for a in live.engine.active_conditions() {
        log_alarm(&a, live.bar.as_ref(), true);
        live.hooks.extend(run_hook(&live.hook, &a, true));
    }
    let link = match cfg.source.kind {
        crate::archive::SourceKind::Protocol => {
            let mut link_spec = cfg.link.clone();
            link_spec.port = session.info.port.clone();
            tokio::spawn(super::link::run(link_spec, ev_tx, link_rx, stop_rx))
        }
        crate::archive::SourceKind::Files => {
            eprintln!(
                "goniowatch: files source{}: captures are placed by their {} in {}; with no controller there is no encoder pose (the plan's pose is assumed), no drift probe and no PAUSE",
                if opts.finished_set { " (a finished set)" } else { " (watching)" },
                if cfg.source.sidecar.is_some() { "sidecar rows" } else { "file names" },
                session.info.capture_root.display()
            );
            let archive = super::archive::ArchiveLink {
                root: session.info.capture_root.clone(),
                spec: cfg.source.clone(),
                plan: crate::setup::plan(cfg)?,
                rig: crate::measure::kinematics::Rig::new(cfg.rig.clone())?,
                finished: opts.finished_set,
                prior: if watch_files {
                    live.engine
                        .announced_captures()
                        .into_iter()
                        .map(|(a, usable)| {
                            let c = crate::archive::listing::ArchiveCapture {
                                file: a.file,
                                entry: a.entry,
                                t: a.t,
                                pose: a.cmd,
                                sub: a.substitute,
                                exposure: a.exposure,
                            };
                            (a.idx, c, usable)
                        })
                        .collect()
                } else {
                    Vec::new()
                },
                outcomes: watch_files.then_some(verdict_rx),
            };
            tokio::spawn(super::archive::run(archive, ev_tx, link_rx, stop_rx))
        }
    };
    Ok((
        live,
        Channels {
            events: ev_rx,
            stop: stop_tx,
            link,
            already_finished,
        },
    ))
}

/// Carry out inputs as they come, and the 2-s tick (idle question, queued jobs, progress,
/// status, summary), until the run is done or a signal arrives.
async fn steps(live: &mut Live, ch: &mut Channels, keep_running: bool) -> Result<RunEnd> {
    let mut sigterm = tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate())
        .context("cannot install SIGTERM handler")?;
    let mut tick = tokio::time::interval(Duration::from_secs(2));
    let mut last_input = Instant::now();
    loop {
        if ch.already_finished && !keep_running {
            return Ok(RunEnd::Finished {
                critical: live.engine.critical_raised(),
            });
        }
        if live.finished && !keep_running {
            // a files source's listing has named every file it did not place, with why
            if !live.files_source {
                let files = live.unannounced();
                live.process(Input::Unannounced { files })?;
            }
            return Ok(RunEnd::Finished {
                critical: live.engine.critical_raised(),
            });
        }
        tokio::select! {
            ev = ch.events.recv() => {
                let Some(ev) = ev else { return Ok(RunEnd::Signal(0)) };
                if matches!(ev, Input::Rx { .. }) {
                    last_input = Instant::now();
                }
                live.process(ev)?;
            }
            _ = tokio::signal::ctrl_c() => return Ok(RunEnd::Signal(2)),
            _ = sigterm.recv() => return Ok(RunEnd::Signal(15)),
            _ = tick.tick() => {
                if last_input.elapsed() >= IDLE_AFTER {
                    last_input = Instant::now();
                    live.process(Input::Idle)?;
                }
                live.submit_pending();
                live.update_progress();
                live.publish_status(true);
                live.results.write_summary(&live.engine.summary())?;
            }
        }
    }
}

/// Stop the link, give alarm hooks their time, flush everything. Workers still retrying are
/// abandoned: their captures are redone on resume.
async fn shutdown(mut live: Live, ch: Channels) -> Result<Summary> {
    let _ = ch.stop.send(true);
    let _ = tokio::time::timeout(Duration::from_secs(2), ch.link).await;
    // each hook has its own 10 s limit
    for h in live.hooks.drain(..) {
        let _ = tokio::time::timeout(Duration::from_secs(11), h).await;
    }
    live.results.sync()?;
    live.journal.sync()?;
    let summary = live.engine.summary();
    live.results.write_summary(&summary)?;
    live.publish_status(true);
    if let Some(b) = &live.bar {
        b.finish_and_clear();
    }
    drop(live.pool);
    Ok(summary)
}
