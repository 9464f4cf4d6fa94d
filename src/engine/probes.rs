//! When a probe round is asked for: every `every` regular captures the controller announced.
//! Counting announcements (not captures checked) keeps the probes evenly spaced in the rig's
//! time however far checking lags behind. What a round holds is the checker's
//! (`Checker::probe_round`).

/// The probe cadence of a session.
#[derive(Debug, Clone, Default)]
pub(super) struct ProbeCadence {
    /// A round every this many regular captures announced (0: never).
    every: u64,
    /// Regular captures announced at which the next round is due. A round that falls due
    /// before the probe's pose is known (or while the link is down) is asked for as soon as
    /// it can be.
    due_at: u64,
    /// Distinct regular captures the controller announced.
    announced: u64,
}

impl ProbeCadence {
    pub(super) fn new(every: u64) -> Self {
        ProbeCadence {
            every,
            due_at: every,
            announced: 0,
        }
    }

    /// A regular capture was announced.
    pub(super) fn handle_announced(&mut self) {
        self.announced += 1;
    }

    /// Whether a round is due.
    pub(super) fn is_due(&self) -> bool {
        self.every > 0 && self.announced >= self.due_at
    }

    /// Regular captures announced so far.
    pub(super) fn announced(&self) -> u64 {
        self.announced
    }

    /// The due round was asked for: the next is due at the next multiple of the cadence, so
    /// a late round does not shift the ones after it.
    pub(super) fn handle_asked(&mut self) {
        if let Some(rounds) = self.announced.checked_div(self.every) {
            self.due_at = (rounds + 1) * self.every;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rounds_fall_due_on_multiples_and_a_late_one_does_not_shift_the_rest() {
        let mut c = ProbeCadence::new(10);
        for _ in 0..9 {
            c.handle_announced();
        }
        assert!(!c.is_due());
        c.handle_announced();
        assert!(c.is_due());
        // asked late, at 13: the next is due at 20, not 23
        for _ in 0..3 {
            c.handle_announced();
        }
        c.handle_asked();
        assert!(!c.is_due());
        for _ in 0..7 {
            c.handle_announced();
        }
        assert!(c.is_due() && c.announced() == 20);
        // never without a cadence
        let mut off = ProbeCadence::new(0);
        off.handle_announced();
        assert!(!off.is_due());
        off.handle_asked();
    }
}
