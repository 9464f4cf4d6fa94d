//! The controller's messages, typed (docs/protocol.md): what the engine sees of a line. A line
//! that frames but whose content the checks cannot use is a typed error, never a panic.

use super::frame::{parse_line, parse_pose, ContentError, LineError, Message};

/// Controller times outside this range (seconds) are refused as garbage.
pub const MAX_CONTROLLER_T: f64 = 1e7;

/// A line from the controller, parsed and typed: what the engine sees.
#[derive(Debug, Clone, PartialEq)]
pub struct Line {
    pub seq: u32,
    pub message: FromController,
}

/// The messages a controller sends (docs/protocol.md). Fields the engine does not use are not
/// kept; a field that is absent or does not parse is `None`.
#[derive(Debug, Clone, PartialEq)]
pub enum FromController {
    Ident(Ident),
    Ack(Ack),
    Nak(Nak),
    Status(Status),
    Capture(Announcement),
    /// `POSE` and `ERR`: for the operator's log, not for the checks.
    Info,
    /// A verb this build does not know.
    Unknown(String),
}

#[derive(Debug, Clone, PartialEq, Default)]
pub struct Ident {
    pub proto: Option<String>,
    pub boot: Option<u64>,
    pub captures: Option<u64>,
    pub session: Option<String>,
    pub rig: Option<String>,
}

#[derive(Debug, Clone, PartialEq, Default)]
pub struct Ack {
    /// The sequence number of the command acknowledged.
    pub reference: Option<u32>,
    pub next: Option<u64>,
    pub state: Option<String>,
}

#[derive(Debug, Clone, PartialEq, Default)]
pub struct Nak {
    /// The sequence number of the command refused (absent or -1: a line that failed its CRC).
    pub reference: Option<u32>,
    pub reason: Option<String>,
    pub supported: Option<String>,
}

#[derive(Debug, Clone, PartialEq, Default)]
pub struct Status {
    pub state: Option<String>,
    pub next: Option<u64>,
    pub reason: Option<String>,
    /// Controller time, when finite and within [0, `MAX_CONTROLLER_T`].
    pub t: Option<f64>,
}

/// A `CAPTURE` line: a capture was taken and its file written.
#[derive(Debug, Clone, PartialEq)]
pub struct Announcement {
    pub idx: u64,
    pub entry: usize,
    /// Relative to the capture root; untrusted.
    pub file: String,
    pub t: f64,
    pub cmd: [f64; 4],
    pub enc: [f64; 4],
    /// The θi used when the entry was taken at a substitute pose.
    pub substitute: Option<f64>,
    /// The capture's exposure relative to the session's (`exposure=`, positive): its linear
    /// values are divided by it, for captures taken at different exposures (LDR archives).
    pub exposure: Option<f64>,
    pub probe: bool,
    /// Re-sent for a `RESYNC`.
    pub replay: bool,
}

/// Parse one line into a typed message, telling a line corrupted on the wire from an intact
/// line with bad content.
pub fn parse_message(line: &str) -> Result<Line, LineError> {
    let m = parse_line(line)?;
    let message = match m.verb.as_str() {
        "IDENT" => FromController::Ident(Ident {
            proto: m.get("proto").map(str::to_string),
            boot: m.get_u64("boot"),
            captures: m.get_u64("captures"),
            session: m.get("session").map(str::to_string),
            rig: m.get("rig").map(str::to_string),
        }),
        "ACK" => FromController::Ack(Ack {
            reference: m.get("ref").and_then(|r| r.parse::<u32>().ok()),
            next: m.get_u64("next"),
            state: m.get("state").map(str::to_string),
        }),
        "NAK" => FromController::Nak(Nak {
            reference: m.get("ref").and_then(|r| r.parse::<u32>().ok()),
            reason: m.get("reason").map(str::to_string),
            supported: m.get("supported").map(str::to_string),
        }),
        "STATUS" => FromController::Status(Status {
            state: m.get("state").map(str::to_string),
            next: m.get_u64("next"),
            reason: m.get("reason").map(str::to_string),
            t: m.get_f64("t")
                .filter(|t| (0.0..=MAX_CONTROLLER_T).contains(t)),
        }),
        "CAPTURE" => FromController::Capture(announcement(&m).map_err(|reason| {
            LineError::Content {
                seq: m.seq,
                verb: m.verb.clone(),
                idx: m.get_u64("idx"),
                replay: m.get("replay") == Some("1"),
                error: ContentError::Announcement {
                    reason,
                    fields: m
                        .fields
                        .iter()
                        .map(|(k, v)| format!("{k}={v}"))
                        .collect::<Vec<_>>()
                        .join(" "),
                },
            }
        })?),
        "POSE" | "ERR" => FromController::Info,
        other => FromController::Unknown(other.to_string()),
    };
    Ok(Line {
        seq: m.seq,
        message,
    })
}

fn announcement(m: &Message) -> Result<Announcement, String> {
    let idx = m.get_u64("idx").ok_or("missing or bad idx")?;
    let entry = m.get_u64("entry").ok_or("missing or bad entry")? as usize;
    let file = m
        .get("file")
        .filter(|f| !f.is_empty())
        .ok_or("missing file")?
        .to_string();
    let t = m.get_f64("t").ok_or("missing or bad t")?;
    if !(0.0..=MAX_CONTROLLER_T).contains(&t) {
        return Err(format!(
            "t = {t} s is outside any plausible controller time [0, {MAX_CONTROLLER_T:e}]"
        ));
    }
    let cmd = m
        .get("cmd")
        .and_then(parse_pose)
        .ok_or("missing or bad cmd")?;
    let enc = m
        .get("enc")
        .and_then(parse_pose)
        .ok_or("missing or bad enc")?;
    let substitute = match m.get("sub") {
        None => None,
        Some(s) => Some(
            s.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or("bad sub")?,
        ),
    };
    let exposure = match m.get("exposure") {
        None => None,
        Some(s) => Some(
            s.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite() && *v > 0.0)
                .ok_or("bad exposure (a positive number)")?,
        ),
    };
    Ok(Announcement {
        idx,
        entry,
        file,
        t,
        cmd,
        enc,
        substitute,
        exposure,
        probe: m.get("probe") == Some("1"),
        replay: m.get("replay") == Some("1"),
    })
}
