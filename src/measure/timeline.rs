//! A time line: capture times in check order, with any step back removed.
//!
//! The controller's `t` is monotonic (docs/protocol.md); file modification times and sidecar
//! times are meant to be. A capture whose time is earlier than the capture checked before it by
//! more than [`STEP_BACK_SLACK_S`] means a clock was set back (or the files' times were changed):
//! the drift models would see the same hour twice. The step is removed from that capture's time
//! and every later one, so the time line goes on in capture order from where it stood, and the
//! step is reported once for the engine to alarm.
//!
//! The engine keeps one for the controller's clock; watch mode keeps one for file times, which
//! it computes itself (a time before the session's first capture would otherwise be negative).

/// How far a capture's time may lie before the previous one's without being a step back
/// (two files written in the same second, times rounded to whole seconds).
pub(crate) const STEP_BACK_SLACK_S: f64 = 1.0;

/// A clock that went back.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct StepBack {
    /// How far back it went (seconds, > 0).
    pub step_s: f64,
    /// The capture's time as announced, and the time of the capture before it (on the time line).
    pub announced_s: f64,
    pub previous_s: f64,
    /// Seconds added to announced times from this capture on: the sum of the steps so far.
    pub shift_s: f64,
}

#[derive(Debug, Clone, Default)]
pub(crate) struct TimeLine {
    /// The time line's time of the last capture checked.
    last: Option<f64>,
    /// Seconds added to announced times: the sum of the steps back so far.
    shift: f64,
}

impl TimeLine {
    /// The time line's time of a capture announced at `t` (checked in index order), and the
    /// step back it shows, if any.
    pub(crate) fn handle_capture(&mut self, t: f64) -> (f64, Option<StepBack>) {
        let mut on_line = t + self.shift;
        let mut step = None;
        if let Some(last) = self.last {
            if on_line < last - STEP_BACK_SLACK_S {
                let step_s = last - on_line;
                self.shift += step_s;
                on_line = last;
                step = Some(StepBack {
                    step_s,
                    announced_s: t,
                    previous_s: last,
                    shift_s: self.shift,
                });
            }
        }
        self.last = Some(self.last.map_or(on_line, |l| l.max(on_line)));
        (on_line, step)
    }

    /// Seconds added to the announced times since the steps back (0 when there were none).
    #[cfg(test)]
    pub(crate) fn shift_s(&self) -> f64 {
        self.shift
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn monotonic_times_pass_unchanged() {
        let mut tl = TimeLine::default();
        for t in [0.0, 7.0, 7.0, 14.5, 14.2, 100.0] {
            // 14.2 after 14.5 is within the slack: kept as announced
            assert_eq!(tl.handle_capture(t), (t, None));
        }
        assert_eq!(tl.shift_s(), 0.0);
    }

    #[test]
    fn a_step_back_is_reported_once_and_removed_from_later_times() {
        let mut tl = TimeLine::default();
        assert_eq!(tl.handle_capture(3600.0).0, 3600.0);
        assert_eq!(tl.handle_capture(3607.0).0, 3607.0);
        // the clock is set back by an hour
        let (t, step) = tl.handle_capture(14.0);
        assert_eq!(t, 3607.0);
        let step = step.unwrap();
        assert_eq!(step.step_s, 3593.0);
        assert_eq!((step.announced_s, step.previous_s), (14.0, 3607.0));
        // later captures go on from there, 7 s apart as announced
        assert_eq!(tl.handle_capture(21.0), (3614.0, None));
        assert_eq!(tl.handle_capture(28.0), (3621.0, None));
        // a second step adds to the first
        let (t, step) = tl.handle_capture(0.0);
        assert_eq!((t, step.map(|s| s.step_s)), (3621.0, Some(28.0)));
        assert_eq!(tl.shift_s(), 3621.0);
    }
}
