//! The daemon's commands to the controller (docs/protocol.md, "Commands"), typed both ways:
//! [`ToController::encode`] writes the line the engine sends, [`ToController::from_message`]
//! reads one (the archive controller, the simulated controllers of the tests). A verb or field
//! the protocol does not define is a [`CommandError`] that says which NAK reason it earns.

use super::frame::{format, Message};
use thiserror::Error;

/// One command line from the daemon, without its sequence number.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ToController {
    /// `HELLO proto=<versions> client=<name/version>`: answered with `IDENT`.
    Hello {
        proto: String,
        client: String,
    },
    /// `SUBSCRIBE`: `ACK`, then a `STATUS`; events follow on this link.
    Subscribe,
    /// `RESYNC from=<idx>`: every `CAPTURE` from `from` on, then `ACK … count next state`.
    Resync {
        from: u64,
    },
    /// `POSE?`: the current pose, as `POSE … ref=`.
    PoseQuery,
    /// `PAUSE` and `RESUME` the acquisition.
    Pause,
    Resume,
    /// `PROBE entry=<plan entry>`: a re-capture of that entry between two scheduled captures.
    Probe {
        entry: usize,
    },
}

/// Why a daemon line is not a command; [`CommandError::nak_reason`] is the NAK it earns.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum CommandError {
    #[error("unknown verb {0:?}")]
    UnknownVerb(String),
    #[error("{verb} needs a numeric {field}")]
    BadArgs {
        verb: &'static str,
        field: &'static str,
    },
}

impl CommandError {
    /// The `reason` of the NAK that answers it (docs/protocol.md).
    pub(crate) fn nak_reason(&self) -> &'static str {
        match self {
            CommandError::UnknownVerb(_) => "unknown-verb",
            CommandError::BadArgs { .. } => "bad-args",
        }
    }
}

impl ToController {
    /// The verb on the wire.
    pub(crate) fn verb(&self) -> &'static str {
        match self {
            ToController::Hello { .. } => "HELLO",
            ToController::Subscribe => "SUBSCRIBE",
            ToController::Resync { .. } => "RESYNC",
            ToController::PoseQuery => "POSE?",
            ToController::Pause => "PAUSE",
            ToController::Resume => "RESUME",
            ToController::Probe { .. } => "PROBE",
        }
    }

    /// The fields, in the order they are written.
    pub(crate) fn fields(&self) -> Vec<(&'static str, String)> {
        match self {
            ToController::Hello { proto, client } => {
                vec![("proto", proto.clone()), ("client", client.clone())]
            }
            ToController::Resync { from } => vec![("from", from.to_string())],
            ToController::Probe { entry } => vec![("entry", entry.to_string())],
            ToController::Subscribe
            | ToController::PoseQuery
            | ToController::Pause
            | ToController::Resume => Vec::new(),
        }
    }

    /// The framed line with sequence number `seq` (CRC included, no LF).
    pub(crate) fn encode(&self, seq: u32) -> String {
        format(seq, self.verb(), &self.fields())
    }

    /// The command a parsed line carries. Fields the command does not define are ignored, as
    /// docs/protocol.md asks of a controller.
    pub fn from_message(m: &Message) -> Result<Self, CommandError> {
        let number = |verb: &'static str, field: &'static str| {
            m.get_u64(field)
                .ok_or(CommandError::BadArgs { verb, field })
        };
        Ok(match m.verb.as_str() {
            "HELLO" => ToController::Hello {
                proto: m.get("proto").unwrap_or_default().to_string(),
                client: m.get("client").unwrap_or_default().to_string(),
            },
            "SUBSCRIBE" => ToController::Subscribe,
            "RESYNC" => ToController::Resync {
                from: number("RESYNC", "from")?,
            },
            "POSE?" => ToController::PoseQuery,
            "PAUSE" => ToController::Pause,
            "RESUME" => ToController::Resume,
            "PROBE" => ToController::Probe {
                entry: usize::try_from(number("PROBE", "entry")?).map_err(|_| {
                    CommandError::BadArgs {
                        verb: "PROBE",
                        field: "entry",
                    }
                })?,
            },
            other => return Err(CommandError::UnknownVerb(other.to_string())),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::protocol::parse;

    #[test]
    fn every_command_reads_back_as_itself() {
        let all = [
            ToController::Hello {
                proto: "1".into(),
                client: "goniowatch/0.1.0".into(),
            },
            ToController::Subscribe,
            ToController::Resync { from: 6560 },
            ToController::PoseQuery,
            ToController::Pause,
            ToController::Resume,
            ToController::Probe { entry: 4 },
        ];
        for (seq, c) in all.iter().enumerate() {
            let line = c.encode(seq as u32);
            let m = parse(&line).unwrap();
            assert_eq!(m.seq, seq as u32);
            assert_eq!(m.verb, c.verb());
            assert_eq!(ToController::from_message(&m).unwrap(), *c, "{line}");
        }
    }

    #[test]
    fn the_lines_are_those_of_the_protocol_document() {
        // docs/protocol.md: the daemon asks with `RESYNC from=N`
        let line = ToController::Resync { from: 1204 }.encode(2);
        assert!(line.starts_with("2 RESYNC from=1204*"), "{line}");
        assert_eq!(
            ToController::Subscribe.encode(1),
            format(1, "SUBSCRIBE", &[])
        );
        assert_eq!(
            ToController::Probe { entry: 40 }.encode(7),
            format(7, "PROBE", &[("entry", "40".into())])
        );
    }

    #[test]
    fn an_unknown_verb_or_a_missing_number_earns_its_nak() {
        let unknown = parse(&format(3, "DANCE", &[])).unwrap();
        let e = ToController::from_message(&unknown).unwrap_err();
        assert_eq!(e.nak_reason(), "unknown-verb");
        for line in [
            format(4, "RESYNC", &[]),
            format(5, "RESYNC", &[("from", "-1".into())]),
            format(6, "PROBE", &[("entry", "four".into())]),
        ] {
            let e = ToController::from_message(&parse(&line).unwrap()).unwrap_err();
            assert_eq!(e.nak_reason(), "bad-args", "{line}");
        }
    }
}
