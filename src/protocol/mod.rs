//! The wire: the line framing of docs/protocol.md (`frame`), the controller's messages typed
//! from it (`messages`) and the daemon's commands (`commands`). Pure; the engine consumes
//! `Line`s and produces lines with `ToController::encode`.

mod commands;
mod frame;
mod messages;

pub use commands::{CommandError, ToController};
pub use frame::{
    crc16, decode_value, encode_value, format, parse, parse_line, parse_pose, ContentError,
    FrameError, LineError, Message, MAX_LINE, PROTO_VERSION, SEQ_MOD,
};
pub use messages::{
    parse_message, Ack, Announcement, FromController, Ident, Line, Nak, Status, MAX_CONTROLLER_T,
};
