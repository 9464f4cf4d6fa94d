//! The capture stage: where a capture was taken (the encoder pose, or the commanded pose while
//! an encoder holds a steady offset; against the plan and against the commands) and whether it
//! can be used at all (its outcome, non-finite, clipped and dark pixels, runs of failures).
//! Every later stage works on what this one measured; it never pairs or compares captures.

use super::evidence::{self, Evidence};
use super::records::{CaptureInput, CaptureRecord, CaptureStatus, Outcome};
use super::{Checked, Ctx};
use crate::checks::alarm::{Affects, Alarm, AlarmCode, AlarmKind, Handling, Severity};
use crate::measure::colour::xyz_to_lab;
use crate::measure::geometry::{angle_between, Spherical};
use crate::measure::kinematics::{Incidence, Pose};

/// What the capture stage made of a capture.
pub(super) enum Verdict {
    /// The capture names an entry the plan does not have: nothing else can be checked.
    NotInPlan,
    /// Failed or missing: its record, and nothing for the later stages.
    Unusable(Box<CaptureRecord>),
    /// Usable: its record (the gain correction is the router's to fill in) and what was
    /// measured.
    Usable(Box<CaptureRecord>, Measured),
}

/// A usable capture as the later stages see it.
pub(super) struct Measured {
    pub(super) checked: Checked,
    /// The plan's pose for the entry (the substitute θi where the rig used one).
    pub(super) nominal: Incidence,
    pub(super) light: usize,
    pub(super) camera: usize,
}

/// Counts, the run of consecutive failures, and the pose episodes in progress.
#[derive(Debug, Clone, Default)]
pub(super) struct CaptureStage {
    pub(super) captures: u64,
    pub(super) ok: u64,
    pub(super) failed: u64,
    pub(super) missing: u64,
    pub(super) probes: u64,
    /// Captures placed off the plan, and whose encoders disagreed with the commanded pose.
    pub(super) off_plan: u64,
    pub(super) encoder_mismatch: u64,
    /// Usable or not, captures placed by the commanded pose (a steady encoder offset).
    pub(super) placed_by_command: u64,
    consecutive_failures: u32,
    off_plan_episode: Option<Episode>,
    /// One per axis (joints 1–3, wagon): a mismatch on one axis neither ends nor restarts
    /// another axis's episode.
    encoder_episodes: [Option<Episode>; 4],
}

/// The encoder axes, in the order of `enc` and `cmd`.
const AXES: [&str; 4] = ["joint 1", "joint 2", "joint 3", "wagon"];

/// An encoder offset is steady, and captures are placed by the commanded pose, once it has held
/// for this many captures while the axis was commanded to move: one reading cannot tell a
/// constant offset from a servo still settling or a pose read mid-move, and an axis that was
/// not moved cannot tell an offset encoder from a stuck one.
const STEADY_CAPTURES: u64 = 3;

/// The axes the light sweeps watch from the images (joints 1 and 2, isotropic samples).
const IMAGE_CHECKED: [bool; 4] = [true, true, false, false];

/// What the operator can do when the encoders put a capture off the plan.
const POSE_OFF_PLAN_ACTION: &str = "Check the arm and the wagon for a collision, a stall or lost steps and re-home them; the captures of the episode are on the retake list.";

/// What the operator can do about an encoder that disagrees with its command on `axis`.
fn encoder_action(axis: &str) -> String {
    let verify = if AXES
        .iter()
        .zip(IMAGE_CHECKED)
        .any(|(a, checked)| *a == axis && checked)
    {
        "on an isotropic sample the light sweeps check this joint from the images: if they stay quiet, the arm went where it was told and the encoder needs re-homing or recalibrating; if they name a slip, the captures are where the encoder says and must be retaken"
    } else {
        "nothing in the images checks this axis, so confirm the pose by hand (a test capture against an earlier one of the same pose) before trusting them"
    };
    format!("Check the {axis} encoder, motor and coupling. Once the offset has held for {STEADY_CAPTURES} captures while the axis moved, captures are placed by the commanded pose and their pairs are marked `by_command`; {verify}. Captures placed off the plan before that are retaken.")
}

/// What the output does about a pose episode's captures: off the plan they are wrong and
/// retaken; with only an encoder disagreeing the images may be right.
fn episode_handling(code: AlarmCode) -> Handling {
    if code == AlarmCode::PoseOffPlan {
        Handling::Retake
    } else {
        Handling::Inspect
    }
}

/// A pose condition that holds over consecutive captures: raised once when it starts, cleared
/// once when it ends, counted in between (a constant offset would otherwise raise an alarm on
/// every capture to the end of the run).
#[derive(Debug, Clone, PartialEq)]
struct Episode {
    /// The axis it concerns (encoder mismatch), or "pose".
    axis: &'static str,
    first_idx: u64,
    last_idx: u64,
    captures: u64,
    worst_deg: f64,
    /// Encoder episodes: the current run of captures whose signed offset stayed within the
    /// encoder tolerance of `run_offset` (its first), how long it is, the command at its start
    /// and whether the command has since moved by more than the tolerance.
    run_offset: f64,
    run_captures: u64,
    run_cmd: f64,
    run_moved: bool,
    /// Captures of the episode placed by the commanded pose.
    by_command: u64,
}

impl Episode {
    fn evidence(&self) -> evidence::Episode {
        evidence::Episode {
            axis: self.axis.to_string(),
            captures: self.captures,
            first_idx: self.first_idx,
            last_idx: self.last_idx,
            worst_deg: self.worst_deg,
            by_command: self.by_command,
        }
    }

    /// Note one capture showing the condition on `axis` with error `deg`: the alarm to raise
    /// (from `raise`), when it starts an episode.
    fn note(
        slot: &mut Option<Episode>,
        axis: &'static str,
        idx: u64,
        deg: f64,
        raise: impl FnOnce() -> Alarm,
    ) -> Option<Alarm> {
        match slot {
            Some(e) if e.axis == axis => {
                e.last_idx = idx;
                e.captures += 1;
                e.worst_deg = e.worst_deg.max(deg);
                None
            }
            _ => {
                *slot = Some(Episode {
                    axis,
                    first_idx: idx,
                    last_idx: idx,
                    captures: 1,
                    worst_deg: deg,
                    run_offset: f64::NAN,
                    run_captures: 0,
                    run_cmd: f64::NAN,
                    run_moved: false,
                    by_command: 0,
                });
                Some(raise())
            }
        }
    }

    /// The capture at `idx` does not show the condition: the episode in progress, if any, ends
    /// with an info alarm `<code>-cleared` that sums it up.
    fn clear(
        slot: &mut Option<Episode>,
        code: AlarmCode,
        what: &str,
        idx: u64,
        t: f64,
    ) -> Option<Alarm> {
        let e = slot.take()?;
        Some(
            Alarm::new(
                AlarmKind::Positioning,
                Severity::Info,
                code.cleared().unwrap_or(code),
                format!(
                    "{what} ({}) held for {} capture(s), {} to {}, at most {:.4}°{}; capture {idx} is within tolerance again",
                    e.axis, e.captures, e.first_idx, e.last_idx, e.worst_deg, e.by_command_note()
                ),
            )
            .at(Some(idx), Some(t))
            .with(Evidence::Episode(e.evidence()))
            .affecting(Affects::Between {
                from_idx: e.first_idx,
                to_idx: e.last_idx,
                handling: episode_handling(code),
            }),
        )
    }
}

impl Episode {
    /// ", N placed by the commanded pose" when any were.
    fn by_command_note(&self) -> String {
        if self.by_command > 0 {
            format!(", {} placed by the commanded pose", self.by_command)
        } else {
            String::new()
        }
    }
}

impl CaptureStage {
    /// The pose episodes still in progress, as the warnings that opened them would read now
    /// (for a status evaluated on start or resume, when the opening alarm is in the past).
    pub(super) fn open_episodes(&self) -> Vec<Alarm> {
        let off_plan = self
            .off_plan_episode
            .iter()
            .map(|e| (AlarmCode::PoseOffPlan, "the pose off the plan", e));
        let encoder = self
            .encoder_episodes
            .iter()
            .flatten()
            .map(|e| (AlarmCode::EncoderMismatch, "the encoder mismatch", e));
        off_plan
            .chain(encoder)
            .map(|(code, what, e)| {
                Alarm::new(
                    AlarmKind::Positioning,
                    Severity::Warning,
                    code,
                    format!(
                        "{what} ({}) has held since capture {}: {} capture(s) to {}, at most {:.4}°{}",
                        e.axis, e.first_idx, e.captures, e.last_idx, e.worst_deg, e.by_command_note()
                    ),
                )
                .with(Evidence::Episode(e.evidence()))
                .advise(
                    &if code == AlarmCode::PoseOffPlan {
                        POSE_OFF_PLAN_ACTION.to_string()
                    } else {
                        encoder_action(e.axis)
                    },
                    Some(Affects::Since { from_idx: e.first_idx, handling: episode_handling(code) }),
                )
            })
            .collect()
    }

    pub(super) fn check(
        &mut self,
        ctx: &Ctx,
        input: &CaptureInput,
        alarms: &mut Vec<Alarm>,
    ) -> Verdict {
        self.captures += 1;
        let at = (Some(input.idx), Some(input.t));
        let Some((nominal, light, camera)) = nominal(ctx, input.entry, input.substitute) else {
            alarms.push(
                Alarm::new(
                    AlarmKind::CaptureQuality,
                    Severity::Warning,
                    AlarmCode::BadEntry,
                    format!(
                        "capture {} names plan entry {}, which is not in the {}-capture plan",
                        input.idx,
                        input.entry,
                        ctx.plan.capture_count()
                    ),
                )
                .at(at.0, at.1),
            );
            return Verdict::NotInPlan;
        };
        let mut rec = CaptureRecord {
            idx: input.idx,
            entry: input.entry,
            light,
            camera,
            probe: input.probe,
            sentinel: false,
            t: input.t,
            file: input.file.clone(),
            status: CaptureStatus::Ok,
            error: None,
            mean_rgb: None,
            xyz: None,
            lab: None,
            pixels: None,
            nonfinite: None,
            clipped: None,
            negative: None,
            angles: None,
            substitute: input.substitute,
            pose_error_deg: None,
            by_command: false,
            gain_corrected: None,
        };
        if input.probe {
            self.probes += 1;
        }
        let placed = self.pose(ctx, input, nominal, alarms);
        let (measured, pose_err) = (placed.incidence, placed.pose_err);
        rec.angles = Some(measured.angles());
        rec.pose_error_deg = Some(pose_err);
        rec.by_command = placed.by_command;

        let stats = match &input.outcome {
            Outcome::Ok { stats, .. } => *stats,
            Outcome::Failed { error } | Outcome::Missing { reason: error } => {
                let missing = matches!(input.outcome, Outcome::Missing { .. });
                rec.status = if missing {
                    CaptureStatus::Missing
                } else {
                    CaptureStatus::Failed
                };
                rec.error = Some(error.clone());
                alarms.push(self.failure(ctx, input, missing, error));
                return Verdict::Unusable(Box::new(rec));
            }
        };
        self.consecutive_failures = 0;
        self.ok += 1;
        let xyz = ctx.xyz_of(stats.mean_rgb);
        rec.mean_rgb = Some(stats.mean_rgb);
        rec.xyz = Some(xyz);
        rec.lab = Some(xyz_to_lab(xyz, ctx.colour.white));
        rec.pixels = Some(stats.pixels);
        rec.nonfinite = Some(stats.nonfinite);
        rec.clipped = Some(stats.clipped);
        rec.negative = Some(stats.negative);
        quality(ctx, input, &stats, xyz[1], alarms);
        let checked = Checked {
            idx: input.idx,
            t: input.t,
            xyz,
            theta_i_deg: Spherical::from_vector(&measured.omega_i).theta_deg(),
            omega_i: measured.omega_i,
            omega_o: measured.omega_o,
            exact_pose: pose_err <= ctx.spec.pair_tolerance_deg,
            by_command: placed.by_command,
            dark: xyz[1] <= ctx.spec.dark_y,
            substitute: input.substitute.is_some(),
        };
        Verdict::Usable(
            Box::new(rec),
            Measured {
                checked,
                nominal,
                light,
                camera,
            },
        )
    }

    /// A failed or missing capture: counted, and critical once `failures_critical` come in a
    /// row.
    fn failure(&mut self, ctx: &Ctx, input: &CaptureInput, missing: bool, error: &str) -> Alarm {
        if missing {
            self.missing += 1;
        } else {
            self.failed += 1;
        }
        self.consecutive_failures += 1;
        let critical = self.consecutive_failures >= ctx.spec.failures_critical;
        Alarm::new(
            AlarmKind::CaptureQuality,
            if critical {
                Severity::Critical
            } else {
                Severity::Warning
            },
            if missing {
                AlarmCode::MissingCapture
            } else {
                AlarmCode::CaptureFailed
            },
            format!(
                "capture {} ({}) {}: {error}{}",
                input.idx,
                input.file,
                if missing {
                    "is missing"
                } else {
                    "could not be used"
                },
                if critical {
                    format!(
                        "; {} captures in a row have failed",
                        self.consecutive_failures
                    )
                } else {
                    String::new()
                }
            ),
        )
        .at(Some(input.idx), Some(input.t))
        .with(Evidence::CaptureFailure(evidence::CaptureFailure {
            file: input.file.clone(),
            consecutive_failures: self.consecutive_failures,
        }))
    }
}

/// The plan's incidence for an entry (with the substitute θi where the rig used one), and its
/// light and camera directions.
fn nominal(ctx: &Ctx, entry: usize, substitute: Option<f64>) -> Option<(Incidence, usize, usize)> {
    let e = ctx.plan.entry(entry).ok()?;
    let dirs = ctx.plan.directions();
    let (l, c) = (dirs[e.light], dirs[e.camera]);
    let theta_i = substitute.unwrap_or(l.theta_deg);
    Some((
        Incidence {
            omega_i: Spherical::from_deg(theta_i, l.phi_deg).to_vector(),
            omega_o: c.spherical().to_vector(),
        },
        e.light,
        e.camera,
    ))
}

impl CaptureStage {
    /// Where the capture is placed, its largest angle from the plan, whether it was placed by
    /// the commanded pose, and the pose alarms: encoders against the commands, and the pose
    /// off the plan, each raised when it starts and cleared when it ends.
    ///
    /// A capture is placed by its encoder pose (the plan's when that is unusable) unless every
    /// encoder that disagrees with its command has done so by one steady offset for
    /// `STEADY_CAPTURES` captures while its axis moved, and the commanded pose is on the plan:
    /// then it is placed by the commanded pose and flagged, since a constant offset that
    /// follows the commands is what a slipped or mis-homed encoder gives while the arm still
    /// goes where it is told (a servo that stalls moves the images too, which the light sweeps
    /// see on joints 1 and 2 of an isotropic sample). The plan is judged against the pose the
    /// capture is placed by, so a capture placed off it is retaken.
    fn pose(
        &mut self,
        ctx: &Ctx,
        input: &CaptureInput,
        nominal: Incidence,
        alarms: &mut Vec<Alarm>,
    ) -> Placed {
        let at = (Some(input.idx), Some(input.t));
        let mismatched = self.encoders(ctx, input, alarms);
        let encoder = match ctx.rig.forward(&Pose {
            joints_deg: [input.enc[0], input.enc[1], input.enc[2]],
            wagon_deg: input.enc[3],
        }) {
            Ok(m) => m,
            Err(e) => {
                alarms.push(
                    Alarm::new(
                        AlarmKind::Positioning,
                        Severity::Warning,
                        AlarmCode::BadPose,
                        format!(
                            "capture {}: encoder pose {:?} unusable ({e}); the plan's pose is assumed",
                            input.idx, input.enc
                        ),
                    )
                    .at(at.0, at.1)
                    .advise(
                        "Check the controller's encoder report for this capture; it was placed at the plan's pose.",
                        Some(Affects::Captures { idx: vec![input.idx], handling: Handling::Inspect }),
                    ),
                );
                nominal
            }
        };
        let off_plan = |m: &Incidence| {
            angle_between(&m.omega_i, &nominal.omega_i)
                .max(angle_between(&m.omega_o, &nominal.omega_o))
                .to_degrees()
        };
        let encoder_err = off_plan(&encoder);
        let commanded = if mismatched {
            ctx.rig
                .forward(&Pose {
                    joints_deg: [input.cmd[0], input.cmd[1], input.cmd[2]],
                    wagon_deg: input.cmd[3],
                })
                .ok()
                .map(|m| {
                    let err = off_plan(&m);
                    (m, err)
                })
        } else {
            None
        };
        let placed = match commanded {
            Some((m, err)) if err <= ctx.spec.pose_tolerance_deg && self.steady_offsets() => {
                self.placed_by_command += 1;
                for e in self.encoder_episodes.iter_mut().flatten() {
                    e.by_command += 1;
                }
                Placed {
                    incidence: m,
                    pose_err: err,
                    by_command: true,
                }
            }
            _ => Placed {
                incidence: encoder,
                pose_err: encoder_err,
                by_command: false,
            },
        };
        let judged_err = placed.pose_err;
        if judged_err > ctx.spec.pose_tolerance_deg {
            self.off_plan += 1;
            let what = if placed.by_command {
                "commands"
            } else {
                "encoders"
            };
            alarms.extend(Episode::note(&mut self.off_plan_episode, "pose", input.idx, judged_err, || {
                Alarm::new(
                    AlarmKind::Positioning,
                    Severity::Warning,
                    AlarmCode::PoseOffPlan,
                    format!(
                        "capture {}: the {what} put the lamp/camera {:.3}° from plan entry {} (tolerance {}°); further captures off the plan are counted until it clears",
                        input.idx, judged_err, input.entry, ctx.spec.pose_tolerance_deg
                    ),
                )
                .at(at.0, at.1)
                .with(Evidence::PoseError(evidence::PoseError { pose_error_deg: judged_err, enc: input.enc, cmd: input.cmd }))
                .advise(
                    POSE_OFF_PLAN_ACTION,
                    Some(Affects::Since { from_idx: input.idx, handling: Handling::Retake }),
                )
            }));
        } else {
            alarms.extend(Episode::clear(
                &mut self.off_plan_episode,
                AlarmCode::PoseOffPlan,
                "the pose off the plan",
                input.idx,
                input.t,
            ));
        }
        placed
    }

    /// Every encoder against its command: each axis's mismatch episode noted, raised or
    /// cleared. Whether any axis disagrees.
    fn encoders(&mut self, ctx: &Ctx, input: &CaptureInput, alarms: &mut Vec<Alarm>) -> bool {
        let at = (Some(input.idx), Some(input.t));
        let tol = ctx.spec.encoder_tolerance_deg;
        let mut mismatched = false;
        for (k, name) in AXES.iter().copied().enumerate() {
            let offset = input.enc[k] - input.cmd[k];
            let slot = &mut self.encoder_episodes[k];
            // NaN readings count as disagreeing, and never as steady
            if !(offset.abs() <= tol) {
                mismatched = true;
                alarms.extend(Episode::note(slot, name, input.idx, offset.abs(), || {
                    Alarm::new(
                        AlarmKind::Positioning,
                        Severity::Warning,
                        AlarmCode::EncoderMismatch,
                        format!(
                            "capture {}: {name} encoder reads {:.4}° but {:.4}° was commanded (|Δ| {:.4}° > {tol}°); further mismatching captures are counted until it clears",
                            input.idx, input.enc[k], input.cmd[k], offset.abs()
                        ),
                    )
                    .at(at.0, at.1)
                    .with(Evidence::EncoderReading(evidence::EncoderReading { axis: name.to_string(), enc: input.enc, cmd: input.cmd }))
                    .advise(
                        &encoder_action(name),
                        Some(Affects::Since { from_idx: input.idx, handling: Handling::Inspect }),
                    )
                }));
                if let Some(e) = slot {
                    // a new run starts when the offset moves (or at the episode's first capture)
                    let same = e.run_captures > 0
                        && offset.is_finite()
                        && (offset - e.run_offset).abs() <= tol;
                    if same {
                        e.run_captures += 1;
                        e.run_moved |= (input.cmd[k] - e.run_cmd).abs() > tol;
                    } else {
                        e.run_offset = offset;
                        e.run_captures = u64::from(offset.is_finite());
                        e.run_cmd = input.cmd[k];
                        e.run_moved = false;
                    }
                }
            } else {
                alarms.extend(Episode::clear(
                    slot,
                    AlarmCode::EncoderMismatch,
                    "the encoder mismatch",
                    input.idx,
                    input.t,
                ));
            }
        }
        if mismatched {
            self.encoder_mismatch += 1;
        }
        mismatched
    }

    /// Whether every encoder episode in progress is in a run of at least `STEADY_CAPTURES`
    /// captures of one offset (within the encoder tolerance of the run's first) during which
    /// its axis was commanded to move.
    fn steady_offsets(&self) -> bool {
        let mut open = self.encoder_episodes.iter().flatten().peekable();
        open.peek().is_some() && open.all(|e| e.run_captures >= STEADY_CAPTURES && e.run_moved)
    }
}

/// Where the pose stage placed a capture.
struct Placed {
    incidence: Incidence,
    /// Its largest angle from the plan (degrees).
    pose_err: f64,
    /// Placed by the commanded pose (a steady encoder offset), not by the encoders.
    by_command: bool,
}

/// The quality alarms of a usable capture: non-finite, clipped and dark pixels.
fn quality(
    ctx: &Ctx,
    input: &CaptureInput,
    stats: &crate::measure::averaging::CaptureStats,
    y: f64,
    alarms: &mut Vec<Alarm>,
) {
    let at = (Some(input.idx), Some(input.t));
    if stats.nonfinite > ctx.spec.nonfinite_max {
        alarms.push(
            Alarm::new(
                AlarmKind::CaptureQuality,
                Severity::Warning,
                AlarmCode::NonFinitePixels,
                format!(
                    "capture {}: {} of {} pixels are NaN or infinite (allowed {}); they are left out of the mean",
                    input.idx, stats.nonfinite, stats.pixels, ctx.spec.nonfinite_max
                ),
            )
            .at(at.0, at.1)
            .with(Evidence::NonFinite(evidence::NonFinite { nonfinite: stats.nonfinite, pixels: stats.pixels })),
        );
    }
    let clipped_fraction = stats.clipped as f64 / stats.pixels.max(1) as f64;
    if clipped_fraction > ctx.spec.clipped_fraction_max {
        alarms.push(
            Alarm::new(
                AlarmKind::CaptureQuality,
                Severity::Warning,
                AlarmCode::ClippedPixels,
                format!(
                    "capture {}: {:.2} % of the pixels are clipped (allowed {:.2} %)",
                    input.idx,
                    100.0 * clipped_fraction,
                    100.0 * ctx.spec.clipped_fraction_max
                ),
            )
            .at(at.0, at.1)
            .with(Evidence::Clipped(evidence::Clipped {
                clipped: stats.clipped,
                pixels: stats.pixels,
                max_value: stats.max_value,
            })),
        );
    }
    if y <= ctx.spec.dark_y {
        alarms.push(
            Alarm::new(
                AlarmKind::CaptureQuality,
                Severity::Warning,
                AlarmCode::DarkCapture,
                format!(
                    "capture {}: mean Y = {:.4} is at or below the dark level {} (lamp off or shutter closed?)",
                    input.idx, y, ctx.spec.dark_y
                ),
            )
            .at(at.0, at.1)
            .with(Evidence::Dark(evidence::Dark { y })),
        );
    }
}
