//! Line framing of docs/protocol.md (pure): `SEQ VERB key=value …*CRC16`, CRC-16/CCITT-FALSE,
//! percent-encoded values. Parsing never panics; every malformed line is a typed error, and a
//! line corrupted on the wire is told from an intact line with a bad field.

use thiserror::Error;

/// A line, LF included, is at most this many bytes.
pub const MAX_LINE: usize = 512;
/// Sequence numbers wrap at this value.
pub const SEQ_MOD: u32 = 1_000_000;
/// The protocol version this build speaks.
pub const PROTO_VERSION: u32 = 1;

#[derive(Debug, Error, Clone, PartialEq, Eq)]
pub enum FrameError {
    #[error("line longer than {MAX_LINE} bytes")]
    TooLong,
    #[error("line is not printable ASCII")]
    NotAscii,
    #[error("line has no CRC")]
    MissingCrc,
    #[error("CRC mismatch (line says {got}, computed {want:04X})")]
    BadCrc { got: String, want: u16 },
    #[error("bad sequence number '{0}'")]
    BadSeq(String),
    #[error("line has no verb")]
    MissingVerb,
    #[error("bad field '{0}'")]
    BadField(String),
    #[error("duplicate key '{0}'")]
    DuplicateKey(String),
}

/// CRC-16/CCITT-FALSE: poly 0x1021, init 0xFFFF, no reflection, no final XOR.
pub fn crc16(data: &[u8]) -> u16 {
    let mut crc: u16 = 0xFFFF;
    for &b in data {
        crc ^= (b as u16) << 8;
        for _ in 0..8 {
            crc = if crc & 0x8000 != 0 {
                (crc << 1) ^ 0x1021
            } else {
                crc << 1
            };
        }
    }
    crc
}

fn is_safe(b: u8) -> bool {
    (0x21..=0x7E).contains(&b) && b != b'%' && b != b'*' && b != b'='
}

/// Percent-encode a value (bytes outside 0x21–0x7E and `%`, `*`, `=`).
pub fn encode_value(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for &b in text.as_bytes() {
        if is_safe(b) {
            out.push(b as char);
        } else {
            out.push_str(&format!("%{b:02X}"));
        }
    }
    out
}

/// Decode a percent-encoded value.
pub fn decode_value(text: &str) -> Result<String, FrameError> {
    let bytes = text.as_bytes();
    let mut raw = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let hex = text
                .get(i + 1..i + 3)
                .and_then(|h| u8::from_str_radix(h, 16).ok())
                .ok_or_else(|| FrameError::BadField(text.to_string()))?;
            raw.push(hex);
            i += 3;
        } else {
            raw.push(bytes[i]);
            i += 1;
        }
    }
    Ok(String::from_utf8_lossy(&raw).into_owned())
}

/// One parsed line.
#[derive(Debug, Clone, PartialEq)]
pub struct Message {
    pub seq: u32,
    pub verb: String,
    pub fields: Vec<(String, String)>,
}

impl Message {
    pub fn get(&self, key: &str) -> Option<&str> {
        self.fields
            .iter()
            .find(|(k, _)| k == key)
            .map(|(_, v)| v.as_str())
    }
    pub(crate) fn get_u64(&self, key: &str) -> Option<u64> {
        self.get(key)?.parse().ok()
    }
    pub(crate) fn get_f64(&self, key: &str) -> Option<f64> {
        self.get(key)?.parse::<f64>().ok().filter(|v| v.is_finite())
    }
}

/// Why an intact line's content was refused.
#[derive(Debug, Error, Clone, PartialEq, Eq)]
pub enum ContentError {
    /// A field is not `key=value` or its value does not decode.
    #[error("{0}")]
    Field(FrameError),
    /// A `CAPTURE` line without a usable value for a field the checks need.
    #[error("{reason}: {fields}")]
    Announcement { reason: String, fields: String },
}

/// Why a received line was not accepted.
#[derive(Debug, Error, Clone, PartialEq, Eq)]
pub enum LineError {
    /// Not an intact line of the protocol (CRC, sequence number or verb unreadable): corrupted
    /// on the wire, so nothing in it can be trusted and a resend may fix it.
    #[error("{0}")]
    Frame(FrameError),
    /// The frame is intact (CRC, sequence number and verb check out) but a field is malformed:
    /// the controller sent it so, and a resend repeats it. `idx` is the capture index when the
    /// line names one that reads as a number.
    #[error("line {seq} {verb} from the controller is malformed: {error}")]
    Content {
        seq: u32,
        verb: String,
        idx: Option<u64>,
        /// The line carries `replay=1` (a resend for a `RESYNC`).
        replay: bool,
        error: ContentError,
    },
}

/// Parse one line (without or with its CR LF).
pub fn parse(line: &str) -> Result<Message, FrameError> {
    parse_line(line).map_err(|e| match e {
        LineError::Frame(f) => f,
        LineError::Content {
            error: ContentError::Field(f),
            ..
        } => f,
        LineError::Content { error, .. } => FrameError::BadField(error.to_string()),
    })
}

/// Parse one line, telling a line corrupted on the wire from an intact line with bad content.
pub fn parse_line(line: &str) -> Result<Message, LineError> {
    let (seq, verb, rest) = frame(line).map_err(LineError::Frame)?;
    let fields = parse_fields(rest).map_err(|error| LineError::Content {
        seq,
        verb: verb.to_string(),
        idx: rest
            .split(' ')
            .find_map(|t| t.strip_prefix("idx="))
            .and_then(|v| v.parse().ok()),
        replay: rest.split(' ').any(|t| t == "replay=1"),
        error: ContentError::Field(error),
    })?;
    Ok(Message {
        seq,
        verb: verb.to_string(),
        fields,
    })
}

/// Check a line's frame: length, characters, CRC, sequence number and verb. Returns them and
/// the unparsed fields.
fn frame(line: &str) -> Result<(u32, &str, &str), FrameError> {
    if line.len() + 1 > MAX_LINE {
        return Err(FrameError::TooLong);
    }
    let line = line.strip_suffix('\n').unwrap_or(line);
    let line = line.strip_suffix('\r').unwrap_or(line);
    if !line.bytes().all(|b| (0x20..=0x7E).contains(&b)) {
        return Err(FrameError::NotAscii);
    }
    let star = line.rfind('*').ok_or(FrameError::MissingCrc)?;
    let (payload, crc_text) = (&line[..star], &line[star + 1..]);
    if crc_text.len() != 4 {
        return Err(FrameError::MissingCrc);
    }
    let want = crc16(payload.as_bytes());
    let got_ok = crc_text
        .bytes()
        .all(|b| b.is_ascii_digit() || (b'A'..=b'F').contains(&b))
        && u16::from_str_radix(crc_text, 16).ok() == Some(want);
    if !got_ok {
        return Err(FrameError::BadCrc {
            got: crc_text.to_string(),
            want,
        });
    }
    let mut tokens = payload.split(' ');
    let seq_text = tokens.next().unwrap_or("");
    let seq: u32 = seq_text
        .parse()
        .ok()
        .filter(|s| *s < SEQ_MOD && !seq_text.starts_with('+'))
        .ok_or_else(|| FrameError::BadSeq(seq_text.to_string()))?;
    let verb = tokens
        .next()
        .filter(|v| !v.is_empty())
        .ok_or(FrameError::MissingVerb)?;
    // everything after the verb: empty, or a space and the fields
    let rest = payload.get(seq_text.len() + 1 + verb.len()..).unwrap_or("");
    Ok((seq, verb, rest))
}

/// The `key=value` fields after the verb.
fn parse_fields(rest: &str) -> Result<Vec<(String, String)>, FrameError> {
    let mut fields: Vec<(String, String)> = Vec::new();
    if rest.is_empty() {
        return Ok(fields);
    }
    let rest = rest
        .strip_prefix(' ')
        .ok_or_else(|| FrameError::BadField(rest.to_string()))?;
    for tok in rest.split(' ') {
        let (k, v) = tok
            .split_once('=')
            .ok_or_else(|| FrameError::BadField(tok.to_string()))?;
        if k.is_empty() {
            return Err(FrameError::BadField(tok.to_string()));
        }
        if fields.iter().any(|(key, _)| key == k) {
            return Err(FrameError::DuplicateKey(k.to_string()));
        }
        fields.push((k.to_string(), decode_value(v)?));
    }
    Ok(fields)
}

/// Build one line, without the LF.
pub fn format(seq: u32, verb: &str, fields: &[(&str, String)]) -> String {
    let mut payload = format!("{} {}", seq % SEQ_MOD, verb);
    for (k, v) in fields {
        payload.push(' ');
        payload.push_str(k);
        payload.push('=');
        payload.push_str(&encode_value(v));
    }
    let crc = crc16(payload.as_bytes());
    format!("{payload}*{crc:04X}")
}

/// `q1,q2,q3,w` → four finite numbers.
pub fn parse_pose(text: &str) -> Option<[f64; 4]> {
    let v: Vec<f64> = text
        .split(',')
        .map(|s| s.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .ok()?;
    if v.len() != 4 || !v.iter().all(|x| x.is_finite()) {
        return None;
    }
    Some([v[0], v[1], v[2], v[3]])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn check_value_and_round_trip() {
        assert_eq!(crc16(b"123456789"), 0x29B1);
        let line = format(
            41,
            "CAPTURE",
            &[("idx", "7".into()), ("file", "a b/c*d=e%f.hdr".into())],
        );
        let m = parse(&line).unwrap();
        assert_eq!(m.seq, 41);
        assert_eq!(m.verb, "CAPTURE");
        assert_eq!(m.get("file"), Some("a b/c*d=e%f.hdr"));
        assert_eq!(m.get_u64("idx"), Some(7));
        assert_eq!(parse(&format!("{line}\r\n")).unwrap(), m);
    }

    #[test]
    fn the_docs_first_example_matches_the_simulator() {
        // docs/protocol.md, generated by sim/goniosim/protocol.py
        assert_eq!(
            format(
                0,
                "HELLO",
                &[("proto", "1".into()), ("client", "goniowatch/0.1.0".into())]
            ),
            "0 HELLO proto=1 client=goniowatch/0.1.0*4537"
        );
        assert!(parse("< 0 IDENT".trim_start_matches("< ")).is_err());
        let ident =
            parse("0 IDENT rig=ubo-sim fw=sim-1.0 proto=1 session=demo captures=6561 boot=1*170D")
                .unwrap();
        assert_eq!(ident.get_u64("boot"), Some(1));
    }

    #[test]
    fn rejections() {
        let with_crc = |p: &str| format!("{p}*{:04X}", crc16(p.as_bytes()));
        for (bad, why) in [
            ("1 HELLO proto=1*0000".to_string(), "crc"),
            ("1 HELLO proto=1".to_string(), "no crc"),
            ("1 HELLO proto=1*12".to_string(), "short crc"),
            (with_crc("x HELLO"), "seq"),
            (with_crc("1000000 HELLO"), "seq range"),
            (with_crc("+1 HELLO"), "seq sign"),
            (with_crc("1"), "verb"),
            (with_crc("1 HELLO bad"), "field"),
            (with_crc("1 HELLO a=1 a=2"), "dup"),
            (with_crc("1 HELLO f=%4"), "escape"),
            (with_crc("1 HELLO =3"), "empty key"),
            (with_crc("1 HELLO "), "trailing space"),
            (with_crc("1 HELLO  a=1"), "double space"),
            ("1 HEL\u{1}LO*0000".to_string(), "control"),
            ("1 HÉLLO*0000".to_string(), "non-ascii"),
            ("x".repeat(600), "long"),
        ] {
            assert!(parse(&bad).is_err(), "{why}: {bad}");
        }
        let lower = format(1, "POSE?", &[])
            .to_lowercase()
            .replace("pose?", "POSE?");
        if lower != format(1, "POSE?", &[]) {
            assert!(parse(&lower).is_err());
        }
    }

    #[test]
    fn an_intact_line_with_a_bad_field_is_told_from_a_corrupt_one() {
        let with_crc = |p: &str| format!("{p}*{:04X}", crc16(p.as_bytes()));
        assert_eq!(
            parse_line(&with_crc("17 CAPTURE idx=42 file=a%ZZ.exr")),
            Err(LineError::Content {
                seq: 17,
                verb: "CAPTURE".into(),
                idx: Some(42),
                replay: false,
                error: ContentError::Field(FrameError::BadField("a%ZZ.exr".into()))
            })
        );
        assert!(matches!(
            parse_line(&with_crc("17 CAPTURE idx=x4 file=%")),
            Err(LineError::Content { idx: None, .. })
        ));
        assert!(matches!(
            parse_line("17 CAPTURE idx=42 file=a%ZZ.exr*0000"),
            Err(LineError::Frame(FrameError::BadCrc { .. }))
        ));
    }

    #[test]
    fn poses() {
        assert_eq!(parse_pose("1,2,3.5,-4"), Some([1.0, 2.0, 3.5, -4.0]));
        assert_eq!(parse_pose("1,2,3"), None);
        assert_eq!(parse_pose("1,2,3,nan"), None);
        assert_eq!(parse_pose("1,2,x,4"), None);
    }
}
