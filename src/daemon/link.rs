//! Shell: the serial link to the controller (tokio-serial), framed into lines with tokio-util's
//! `Framed` and `LinesCodec::new_with_max_length`. A line that is too long or not UTF-8 becomes
//! an `RxBad` input instead of ending the stream. On EOF, EIO or an unplugged device the port is
//! reopened at the same path with exponential backoff.

use crate::config::LinkSpec;
use crate::engine::Input;
use crate::protocol::MAX_LINE;
use futures::{SinkExt, StreamExt};
use std::time::Duration;
use tokio::sync::{mpsc, watch};
use tokio_serial::SerialPortBuilderExt;
use tokio_util::bytes::BytesMut;
use tokio_util::codec::{Decoder, Encoder, Framed, LinesCodec, LinesCodecError};

/// `LinesCodec` with a length limit, whose framing errors are items rather than stream errors.
pub(crate) struct RigCodec {
    inner: LinesCodec,
}

impl Default for RigCodec {
    fn default() -> Self {
        RigCodec {
            inner: LinesCodec::new_with_max_length(MAX_LINE - 1),
        }
    }
}

impl Decoder for RigCodec {
    type Item = Result<String, String>;
    type Error = std::io::Error;

    fn decode(&mut self, buf: &mut BytesMut) -> Result<Option<Self::Item>, std::io::Error> {
        match self.inner.decode(buf) {
            Ok(Some(line)) => Ok(Some(Ok(line))),
            Ok(None) => Ok(None),
            Err(LinesCodecError::MaxLineLengthExceeded) => {
                Ok(Some(Err(format!("line longer than {MAX_LINE} bytes"))))
            }
            Err(LinesCodecError::Io(e)) if e.kind() == std::io::ErrorKind::InvalidData => {
                Ok(Some(Err("line is not UTF-8".into())))
            }
            Err(LinesCodecError::Io(e)) => Err(e),
        }
    }
}

impl Encoder<String> for RigCodec {
    type Error = std::io::Error;
    fn encode(&mut self, line: String, buf: &mut BytesMut) -> Result<(), std::io::Error> {
        self.inner.encode(line, buf).map_err(|e| match e {
            LinesCodecError::Io(e) => e,
            LinesCodecError::MaxLineLengthExceeded => std::io::Error::other("line too long"),
        })
    }
}

/// The port's settings from `[link]` (validated ranges: 5–8 data bits, 1–2 stop bits).
fn serial_builder(port: &str, spec: &LinkSpec) -> tokio_serial::SerialPortBuilder {
    use tokio_serial::{DataBits, FlowControl, Parity, StopBits};
    let data_bits = match spec.data_bits {
        5 => DataBits::Five,
        6 => DataBits::Six,
        7 => DataBits::Seven,
        _ => DataBits::Eight,
    };
    let parity = match spec.parity {
        crate::config::Parity::None => Parity::None,
        crate::config::Parity::Odd => Parity::Odd,
        crate::config::Parity::Even => Parity::Even,
    };
    let stop_bits = if spec.stop_bits == 2 {
        StopBits::Two
    } else {
        StopBits::One
    };
    let flow = match spec.flow_control {
        crate::config::FlowControl::None => FlowControl::None,
        crate::config::FlowControl::RtsCts => FlowControl::Hardware,
        crate::config::FlowControl::XonXoff => FlowControl::Software,
    };
    tokio_serial::new(port, spec.baud)
        .data_bits(data_bits)
        .parity(parity)
        .stop_bits(stop_bits)
        .flow_control(flow)
}

/// Run the link until `stop` turns true. Inputs go to `events`; lines to send come from `lines`.
pub(crate) async fn run(
    spec: LinkSpec,
    events: mpsc::UnboundedSender<Input>,
    mut lines: mpsc::UnboundedReceiver<String>,
    mut stop: watch::Receiver<bool>,
) {
    let mut backoff = Duration::from_millis(spec.reconnect_min_ms.max(1));
    let max_backoff =
        Duration::from_millis(spec.reconnect_max_ms.max(spec.reconnect_min_ms).max(1));
    let mut logged_failure = false;
    loop {
        if *stop.borrow() {
            return;
        }
        let port = spec.port.to_string_lossy().into_owned();
        match serial_builder(&port, &spec).open_native_async() {
            Ok(mut stream) => {
                // exclusive mode would lock out a restarted daemon while the port stays open
                if let Err(e) = stream.set_exclusive(false) {
                    tracing::debug!("cannot clear exclusive mode on {port}: {e}");
                }
                tracing::info!("serial port {port} open");
                logged_failure = false;
                let mut seen_line = false;
                // lines queued for a previous connection are stale
                while lines.try_recv().is_ok() {}
                if events.send(Input::Connected).is_err() {
                    return;
                }
                let (mut sink, mut source) = Framed::new(stream, RigCodec::default()).split();
                let reason = loop {
                    tokio::select! {
                        frame = source.next() => match frame {
                            Some(Ok(Ok(line))) => {
                                // a port that opens but never carries a line is flapping: keep
                                // backing off until one arrives
                                if !seen_line {
                                    seen_line = true;
                                    backoff = Duration::from_millis(spec.reconnect_min_ms.max(1));
                                }
                                if events.send(Input::Rx { line }).is_err() { return; }
                            }
                            Some(Ok(Err(reason))) => { if events.send(Input::RxBad { reason }).is_err() { return; } }
                            Some(Err(e)) => break e.to_string(),
                            None => break "end of stream".to_string(),
                        },
                        line = lines.recv() => match line {
                            Some(line) => {
                                if let Err(e) = sink.send(line).await {
                                    break format!("write failed: {e}");
                                }
                            }
                            None => return,
                        },
                        _ = stop.changed() => return,
                    }
                };
                tracing::warn!("serial port {port} lost: {reason}");
                if events.send(Input::Disconnected { reason }).is_err() {
                    return;
                }
            }
            Err(e) => {
                if !logged_failure {
                    tracing::warn!("cannot open serial port {port}: {e}; retrying");
                    logged_failure = true;
                }
            }
        }
        tokio::select! {
            _ = tokio::time::sleep(backoff) => {}
            _ = stop.changed() => return,
        }
        backoff = (backoff * 2).min(max_backoff);
    }
}
