//! Shell: the status server of `run --http ADDR` (axum on the daemon's tokio runtime).
//!
//! - `GET /`             the status page (one self-contained HTML file, live by server-sent events)
//! - `GET /events`       server-sent events: the snapshot now, then on every change
//! - `GET /status.json`  the latest snapshot
//! - `GET /metrics`      Prometheus text exposition
//!
//! Readers take snapshots from a `watch` channel: the run loop never waits for them, and a slow
//! reader skips to the latest snapshot instead of queueing old ones. At most `MAX_STREAMS`
//! event streams are served at once; further ones get 503.

use super::status::{metrics, Published};
use anyhow::{Context, Result};
use axum::extract::State;
use axum::http::{header, StatusCode};
use axum::response::sse::{Event, KeepAlive, Sse};
use axum::response::{Html, IntoResponse, Response};
use axum::routing::get;
use axum::Router;
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::{watch, Semaphore};

pub(crate) type SnapshotRx = watch::Receiver<Option<Arc<Published>>>;

const PAGE: &str = include_str!("status.html");
const MAX_STREAMS: usize = 32;

#[derive(Clone)]
struct AppState {
    rx: SnapshotRx,
    streams: Arc<Semaphore>,
}

/// Refuse a non-loopback address unless the operator allowed it explicitly.
pub(crate) fn check_address(addr: &SocketAddr, allow_remote: bool) -> Result<()> {
    if !addr.ip().to_canonical().is_loopback() && !allow_remote {
        return Err(crate::config::ConfigError::Invalid {
            field: "http.allow_remote",
            message: format!(
                "--http {addr} is not a loopback address; the status page has no \
                 authentication, so serving it beyond this machine needs `allow_remote = true` \
                 under [http] in the session's config"
            ),
        }
        .into());
    }
    Ok(())
}

/// Bind (before the session is opened, so that a bad or busy address leaves nothing behind).
pub(crate) async fn bind(addr: SocketAddr) -> Result<tokio::net::TcpListener> {
    tokio::net::TcpListener::bind(addr)
        .await
        .with_context(|| format!("cannot listen on {addr} for --http"))
}

/// On a loopback address, only requests naming a loopback host are served: a web page the
/// operator visits cannot read the status through a DNS name that resolves to 127.0.0.1.
fn host_allowed(host: Option<&str>) -> bool {
    let Some(host) = host else { return false };
    let name = if let Some(rest) = host.strip_prefix('[') {
        rest.split(']').next().unwrap_or("")
    } else {
        host.rsplit_once(':').map(|(h, _)| h).unwrap_or(host)
    };
    name.eq_ignore_ascii_case("localhost")
        || name
            .parse::<std::net::IpAddr>()
            .is_ok_and(|ip| ip.to_canonical().is_loopback())
}

async fn host_guard(
    State(loopback): State<bool>,
    req: axum::extract::Request,
    next: axum::middleware::Next,
) -> Response {
    let host = req
        .headers()
        .get(header::HOST)
        .and_then(|h| h.to_str().ok());
    if loopback && !host_allowed(host) {
        return (
            StatusCode::FORBIDDEN,
            "the status page answers to localhost only",
        )
            .into_response();
    }
    next.run(req).await
}

/// Serve in the background on a bound listener.
pub(crate) async fn serve(
    listener: tokio::net::TcpListener,
    rx: SnapshotRx,
) -> Result<(SocketAddr, tokio::task::JoinHandle<()>)> {
    let local = listener.local_addr().context("listener address")?;
    let loopback = local.ip().to_canonical().is_loopback();
    let state = AppState {
        rx,
        streams: Arc::new(Semaphore::new(MAX_STREAMS)),
    };
    let app = Router::new()
        .route("/", get(page))
        .route("/events", get(events))
        .route("/status.json", get(status_json))
        .route("/metrics", get(prometheus))
        .with_state(state)
        .layer(axum::middleware::from_fn_with_state(loopback, host_guard));
    let handle = tokio::spawn(async move {
        if let Err(e) = axum::serve(listener, app).await {
            tracing::warn!("status server stopped: {e}");
        }
    });
    Ok((local, handle))
}

async fn page() -> Html<&'static str> {
    Html(PAGE)
}

fn latest(rx: &SnapshotRx) -> Option<Arc<Published>> {
    rx.borrow().clone()
}

async fn status_json(State(s): State<AppState>) -> Response {
    match latest(&s.rx) {
        Some(p) => ([(header::CONTENT_TYPE, "application/json")], p.json.clone()).into_response(),
        None => (StatusCode::SERVICE_UNAVAILABLE, "starting").into_response(),
    }
}

async fn prometheus(State(s): State<AppState>) -> Response {
    match latest(&s.rx) {
        Some(snap) => (
            [(
                header::CONTENT_TYPE,
                "text/plain; version=0.0.4; charset=utf-8",
            )],
            metrics(&snap.snapshot),
        )
            .into_response(),
        None => (StatusCode::SERVICE_UNAVAILABLE, "starting").into_response(),
    }
}

async fn events(State(s): State<AppState>) -> Response {
    let Ok(permit) = s.streams.clone().try_acquire_owned() else {
        return (StatusCode::SERVICE_UNAVAILABLE, "too many status streams").into_response();
    };
    let rx = s.rx.clone();
    // the first event is the current snapshot; then one per change (intermediate ones skipped)
    let stream =
        futures::stream::unfold((rx, true, permit), |(mut rx, first, permit)| async move {
            if !first && rx.changed().await.is_err() {
                return None;
            }
            let snap = rx.borrow_and_update().clone();
            let data = snap.map(|p| p.json.clone()).unwrap_or_else(|| "{}".into());
            Some((
                Ok::<Event, std::convert::Infallible>(Event::default().event("status").data(data)),
                (rx, false, permit),
            ))
        });
    Sse::new(stream)
        .keep_alive(KeepAlive::new().interval(Duration::from_secs(10)))
        .into_response()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn loopback_hosts_only() {
        for ok in [
            "localhost",
            "localhost:8080",
            "127.0.0.1:1",
            "127.3.4.5",
            "[::1]:80",
            "[::ffff:127.0.0.1]:9",
            "LOCALHOST",
        ] {
            assert!(host_allowed(Some(ok)), "{ok}");
        }
        for bad in [
            "evil.example:8080",
            "192.168.1.2",
            "[fe80::1]:80",
            "",
            "localhost.evil.example",
        ] {
            assert!(!host_allowed(Some(bad)), "{bad}");
        }
        assert!(!host_allowed(None));
        assert!(check_address(&"[::ffff:127.0.0.1]:0".parse().unwrap(), false).is_ok());
        assert!(check_address(&"0.0.0.0:0".parse().unwrap(), false).is_err());
        assert!(check_address(&"0.0.0.0:0".parse().unwrap(), true).is_ok());
    }
}
