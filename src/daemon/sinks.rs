//! Shell: alarm sinks besides `alarms.jsonl` (written with the results): the log or the terminal,
//! and an optional command hook that gets the alarm as JSON on its standard input.

use crate::checks::alarm::{Alarm, Severity};
use std::process::Stdio;
use std::time::Duration;
use tokio::io::AsyncWriteExt;

pub(crate) fn format_alarm(a: &Alarm) -> String {
    let sev = match a.severity {
        Severity::Info => "info",
        Severity::Warning => "WARNING",
        Severity::Critical => "CRITICAL",
    };
    let kind = serde_json::to_value(a.kind)
        .ok()
        .and_then(|v| v.as_str().map(str::to_string))
        .unwrap_or_default();
    let mut line = format!("[{sev} {kind}/{}] {}", a.code, a.message);
    if let Some(action) = &a.action {
        line.push_str(" → ");
        line.push_str(action);
    }
    if let Some(affects) = &a.affects {
        line.push_str(&format!(" [{}]", affects.describe()));
    }
    line
}

/// Log one alarm (or print it above the progress bar).
pub(crate) fn log_alarm(a: &Alarm, bar: Option<&indicatif::ProgressBar>, still_active: bool) {
    let mut line = format_alarm(a);
    if still_active {
        line = format!("still active: {line}");
    }
    match bar {
        Some(b) if !b.is_hidden() => b.println(line),
        _ => match a.severity {
            Severity::Info => tracing::info!("{line}"),
            Severity::Warning => tracing::warn!("{line}"),
            Severity::Critical => tracing::error!("{line}"),
        },
    }
}

/// Run the hook command for one alarm, in the background, with a time limit. The caller keeps
/// the handle and waits for it before exiting, so the last alarm's hook is not cut short.
pub(crate) fn run_hook(
    hook: &[String],
    a: &Alarm,
    still_active: bool,
) -> Option<tokio::task::JoinHandle<()>> {
    let (prog, args) = hook.split_first()?;
    let mut value = serde_json::to_value(a).unwrap_or_default();
    if let Some(obj) = value.as_object_mut() {
        obj.insert("wall_ms".into(), crate::session::journal::now_ms().into());
        obj.insert("still_active".into(), still_active.into());
    }
    let payload = serde_json::to_vec(&value).unwrap_or_default();
    let mut cmd = tokio::process::Command::new(prog);
    cmd.args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .kill_on_drop(true);
    let prog = prog.clone();
    Some(tokio::spawn(async move {
        let mut child = match cmd.spawn() {
            Ok(c) => c,
            Err(e) => {
                tracing::warn!("alarm hook {prog} could not start: {e}");
                return;
            }
        };
        if let Some(mut stdin) = child.stdin.take() {
            // a hook that does not read its input must not hold us up
            let _ = tokio::time::timeout(Duration::from_secs(10), stdin.write_all(&payload)).await;
        }
        match tokio::time::timeout(Duration::from_secs(10), child.wait()).await {
            Ok(Ok(s)) if !s.success() => tracing::warn!("alarm hook {prog} exited with {s}"),
            Ok(Err(e)) => tracing::warn!("alarm hook {prog} failed: {e}"),
            Err(_) => {
                tracing::warn!("alarm hook {prog} took longer than 10 s; killed");
                let _ = child.kill().await;
            }
            _ => {}
        }
    }))
}
