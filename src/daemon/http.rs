//! Shell: the status server of `run --http ADDR` (axum on the daemon's tokio runtime).
//!
//! - `GET /`             the status page (one self-contained HTML file, live by server-sent events)
//! - `GET /events`       server-sent events: the snapshot now, then on every change
//! - `GET /status.json`  the latest snapshot
//! - `GET /metrics`      Prometheus text exposition
//! - `GET /alarms`       the alarm catalogue, one entry per code under its anchor `alarm-<code>`
//!   (the status page links each alarm's code to its entry)
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
use std::sync::{Arc, LazyLock};
use std::time::Duration;
use tokio::sync::{watch, Semaphore};

pub(crate) type SnapshotRx = watch::Receiver<Option<Arc<Published>>>;

const PAGE: &str = include_str!("status.html");
/// The catalogue is fixed when goniowatch is built: its page is rendered once, on first request.
static ALARMS_PAGE: LazyLock<String> = LazyLock::new(alarms_page);
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
        .route("/alarms", get(alarms))
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

/// The whole alarm catalogue as one self-contained page, rendered by the catalogue itself (as
/// the report's appendix is), so an entry reads the same in both.
fn alarms_page() -> String {
    use crate::checks::catalogue::{catalogue_html, ENTRY_STYLE};
    format!(
        r##"<!doctype html>
<html lang="en"><head><meta charset="utf-8"><meta name="viewport" content="width=device-width, initial-scale=1">
<title>goniowatch: alarm codes</title><style>
body{{font:14px/1.45 system-ui,-apple-system,"Segoe UI",Roboto,sans-serif;color:#1d232a;max-width:960px;margin:24px auto;padding:0 18px}}
h1{{font-size:20px}} code{{font-size:0.95em}} .muted{{color:#5d6b78}} a{{color:#1f5fa8}}
{ENTRY_STYLE}</style></head><body>
<h1>goniowatch alarm codes</h1>
<p class="muted">Every alarm has a code, a kind and a severity. <b>info</b>: said for the record; <b>warning</b>: look at it, the run goes on; <b>critical</b>: the run cannot be trusted as it goes. The same catalogue is printed by <code>goniowatch alarms</code> and kept in docs/alarms.md. <a href="./">Back to the status page</a>.</p>
{}</body></html>
"##,
        catalogue_html()
    )
}

async fn alarms() -> Html<&'static str> {
    Html(ALARMS_PAGE.as_str())
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

    /// One HTTP/1.1 request to `addr` with `host` as its Host header; returns the whole answer.
    async fn get_raw(addr: SocketAddr, path: &str, host: &str) -> String {
        use tokio::io::{AsyncReadExt, AsyncWriteExt};
        let mut stream = tokio::net::TcpStream::connect(addr).await.unwrap();
        let request = format!("GET {path} HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\n\r\n");
        stream.write_all(request.as_bytes()).await.unwrap();
        let mut answer = Vec::new();
        stream.read_to_end(&mut answer).await.unwrap();
        String::from_utf8(answer).unwrap()
    }

    #[tokio::test]
    async fn alarms_page_has_every_code_behind_the_host_guard() {
        let listener = bind("127.0.0.1:0".parse().unwrap()).await.unwrap();
        let (_tx, rx) = watch::channel(None);
        let (addr, server) = serve(listener, rx).await.unwrap();

        let answer = get_raw(addr, "/alarms", &format!("localhost:{}", addr.port())).await;
        let (head, body) = answer.split_once("\r\n\r\n").unwrap();
        assert!(head.starts_with("HTTP/1.1 200"), "{head}");
        assert!(
            head.to_ascii_lowercase()
                .contains("content-type: text/html"),
            "{head}"
        );
        for code in crate::checks::alarm::AlarmCode::ALL {
            let id = format!("id=\"alarm-{code}\"");
            assert_eq!(body.matches(&id).count(), 1, "{code}");
        }
        assert!(body.contains(crate::checks::catalogue::catalogue_html().as_str()));

        // the host guard covers it as it covers the other routes
        let answer = get_raw(addr, "/alarms", "evil.example").await;
        assert!(answer.starts_with("HTTP/1.1 403"), "{answer}");
        server.abort();
    }
}
