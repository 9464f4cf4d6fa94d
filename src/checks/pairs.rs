//! The pair stage: Helmholtz reciprocity. Each capture against its reciprocal partner when the
//! partner is in (the paper's cosine re-correction; only exact pairs count in Table 2), the
//! outlier test per pair geometry, and the occlusion substitutes, whose partner pose is off the
//! grid: they wait until the partner's light direction is complete and are then scored against
//! a partner interpolated from that direction's captures. A session without substitutes never
//! builds an interpolant.

use super::evidence::{Evidence, PairOutlier};
use super::records::{Interpolation, PairRecord, PairStatus, Table2};
use super::{Checked, Ctx, Ledger};
use crate::checks::alarm::{Affects, Alarm, AlarmCode, AlarmKind, Handling, Severity};
use crate::detect::drift::{mount_coordinates, MountPattern};
use crate::measure::colour::{ciede2000, colour_difference, xyz_to_lab, Xyz};
use crate::measure::geometry::{angle_between, Spherical};
use crate::measure::reciprocity::{pair_residual, PairError};
use crate::measure::resample::{ResampleSpec, Resampler, Sample};
use crate::measure::stats::median_sorted;
use std::collections::HashMap;

/// A substitute capture waiting for its partner's light direction to be complete.
#[derive(Debug, Clone)]
pub(super) struct PendingPartner {
    pub(super) capture: Checked,
    pub(super) entry: usize,
    /// The partner's light direction (the substitute's camera direction).
    pub(super) light: usize,
}

#[derive(Debug, Clone, Default)]
pub(super) struct PairStage {
    pub(super) table2: Table2,
    /// The exact pairs of `table2` with a capture placed by the commanded pose.
    pub(super) by_command_table: Table2,
    pub(super) interpolated_table: Table2,
    /// ΔE00 of exact pairs so far, sorted, per pair geometry (the two nominal θ): real data are
    /// less reciprocal toward grazing angles, so an outlier is judged against its own geometry.
    sorted_de2000: HashMap<(i64, i64), Vec<f64>>,
    pending: Vec<PendingPartner>,
    pub(super) exact: u64,
    pub(super) needs_resampling: u64,
    pub(super) grazing: u64,
    pub(super) interpolated: u64,
    pub(super) unresolved: u64,
}

impl PairStage {
    /// A substitute that will be scored once its partner's light direction is complete.
    pub(super) fn wait_for_partner(&mut self, capture: Checked, entry: usize, light: usize) {
        self.pending.push(PendingPartner {
            capture,
            entry,
            light,
        });
    }

    /// Score a capture against its reciprocal partner if that is in (and neither is dark).
    pub(super) fn pair(
        &mut self,
        ctx: &Ctx,
        ledger: &Ledger,
        entry: usize,
        capture: &Checked,
        mount: Option<&MountPattern>,
        alarms: &mut Vec<Alarm>,
    ) -> Option<PairRecord> {
        let partner_entry = ctx.plan.reciprocal_of(entry).ok()?;
        if partner_entry == entry || capture.dark {
            return None;
        }
        let partner = ledger.get(partner_entry).filter(|p| !p.dark)?;
        let pair = score_pair(ctx, partner, capture, [partner_entry, entry], capture.t);
        if let (Some(d), PairStatus::Exact) = (&pair.diff, pair.status) {
            self.table2.add(d);
            if pair.by_command {
                self.by_command_table.add(d);
            }
            // the outlier test judges what the off-centre mount's pattern, once modelled, does
            // not explain; Table 2 keeps the pair as measured
            let de = match (mount, pair.xyz_a, pair.xyz_b) {
                (Some(m), Some(a), Some(b)) => {
                    let unmounted = |xyz: Xyz, c: &Checked| {
                        let f = (-m.ln_effect(&mount_coordinates(&c.omega_i, &c.omega_o))).exp();
                        xyz.map(|v| v * f)
                    };
                    let white = ctx.colour.white;
                    ciede2000(
                        xyz_to_lab(unmounted(a, partner), white),
                        xyz_to_lab(unmounted(b, capture), white),
                    )
                }
                _ => d.de2000,
            };
            // a non-finite difference has no place in the sorted history of the outlier test
            if de.is_finite() {
                let at = (Some(capture.idx), Some(capture.t));
                alarms.extend(self.outlier(ctx, de, &pair, at));
            }
        }
        match pair.status {
            PairStatus::Exact => self.exact += 1,
            PairStatus::Grazing => self.grazing += 1,
            _ => self.needs_resampling += 1,
        }
        Some(pair)
    }

    /// Whether a substitute waits for a light direction that is now complete.
    pub(super) fn any_ready(&self, ledger: &Ledger) -> bool {
        self.pending.iter().any(|p| ledger.light_complete(p.light))
    }

    /// Score the waiting substitutes for which `ready` holds against their interpolated
    /// partners, in the order they came. Returns each with its pair record.
    pub(super) fn resolve(
        &mut self,
        ctx: &Ctx,
        ledger: &Ledger,
        ready: impl Fn(&PendingPartner, &Ledger) -> bool,
        t: f64,
    ) -> Vec<(PendingPartner, PairRecord)> {
        if self.pending.is_empty() {
            return Vec::new();
        }
        let (ready, wait): (Vec<PendingPartner>, Vec<PendingPartner>) =
            std::mem::take(&mut self.pending)
                .into_iter()
                .partition(|p| ready(p, ledger));
        self.pending = wait;
        let mut slices: HashMap<usize, Result<Resampler, String>> = HashMap::new();
        let mut out = Vec::with_capacity(ready.len());
        for p in ready {
            let slice = slices
                .entry(p.light)
                .or_insert_with(|| slice_of(ctx, ledger, p.light));
            let pair = score_interpolated(ctx, &p, slice, t);
            if pair.status == PairStatus::Interpolated {
                if let Some(d) = &pair.diff {
                    self.interpolated_table.add(d);
                }
                self.interpolated += 1;
            } else {
                self.unresolved += 1;
            }
            out.push((p, pair));
        }
        out
    }

    fn outlier(
        &mut self,
        ctx: &Ctx,
        de: f64,
        pair: &PairRecord,
        at: (Option<u64>, Option<f64>),
    ) -> Option<Alarm> {
        let spec = ctx.spec;
        let bucket = ctx
            .plan
            .entry(pair.entries[0])
            .map(|e| {
                let k = ctx.plan.isotropy_key(&e);
                (k.theta_lo_mdeg, k.theta_hi_mdeg)
            })
            .unwrap_or((0, 0));
        let sorted = self.sorted_de2000.entry(bucket).or_default();
        let pos = sorted.partition_point(|v| *v < de);
        let n = sorted.len();
        let result = if n >= spec.outlier_min_pairs {
            let med = median_sorted(sorted);
            let mut dev: Vec<f64> = sorted.iter().map(|v| (v - med).abs()).collect();
            dev.sort_by(f64::total_cmp);
            let mad = median_sorted(&dev);
            let limit = (med + spec.outlier_k * 1.4826 * mad).max(spec.outlier_floor_de2000);
            (de > limit).then(|| {
                Alarm::new(
                    AlarmKind::ReciprocityOutlier,
                    Severity::Warning,
                    AlarmCode::ReciprocityOutlier,
                    format!(
                        "pair of captures {} and {} (entries {} ↔ {}) differs by ΔE00 = {:.2}, above the limit {:.2} (median {:.2} + {}·MAD over {} pairs at θ {}°/{}°)",
                        pair.a,
                        pair.b,
                        pair.entries[0],
                        pair.entries[1],
                        de,
                        limit,
                        med,
                        spec.outlier_k,
                        n,
                        bucket.0 as f64 / 1000.0,
                        bucket.1 as f64 / 1000.0
                    ),
                )
                .at(at.0, at.1)
                .with(Evidence::PairOutlier(PairOutlier {
                    de2000: de,
                    limit,
                    median: med,
                    mad,
                    pairs: n,
                    a: pair.a,
                    b: pair.b,
                    theta_pair_deg: [bucket.0 as f64 / 1000.0, bucket.1 as f64 / 1000.0],
                }))
                .advise(
                    "Look at the two captures: a single outlier is usually a speck, a glint or a flicker; outliers that recur in one direction point at the sample's mount or a pose error. Retake the pair if one capture is plainly wrong.",
                    Some(Affects::Captures { idx: vec![pair.a, pair.b], handling: Handling::Inspect }),
                )
            })
        } else {
            None
        };
        sorted.insert(pos, de);
        result
    }
}

fn score_pair(
    ctx: &Ctx,
    first: &Checked,
    second: &Checked,
    entries: [usize; 2],
    t: f64,
) -> PairRecord {
    let mismatch = angle_between(&first.omega_i, &second.omega_o)
        .max(angle_between(&first.omega_o, &second.omega_i))
        .to_degrees();
    let mut rec = PairRecord {
        a: first.idx,
        b: second.idx,
        entries,
        status: PairStatus::Grazing,
        mismatch_deg: mismatch,
        t,
        xyz_a: None,
        xyz_b: None,
        diff: None,
        by_command: first.by_command || second.by_command,
        interpolated: None,
    };
    if let Ok(r) = pair_residual(
        first.xyz,
        first.theta_i_deg,
        second.xyz,
        second.theta_i_deg,
        ctx.colour.white,
        ctx.colour.min_cos,
    ) {
        rec.xyz_a = Some(r.xyz1);
        rec.xyz_b = Some(r.xyz2);
        rec.diff = Some(r.diff);
        let exact =
            mismatch <= ctx.spec.pair_tolerance_deg && first.exact_pose && second.exact_pose;
        rec.status = if exact {
            PairStatus::Exact
        } else {
            PairStatus::NeedsResampling
        };
    }
    rec
}

/// The session's captures of one light direction as a slice interpolant.
fn slice_of(ctx: &Ctx, ledger: &Ledger, light: usize) -> Result<Resampler, String> {
    let omega_i = ctx
        .plan
        .directions()
        .get(light)
        .ok_or_else(|| format!("no light direction {light}"))?
        .spherical()
        .to_vector();
    let samples: Vec<Sample> = ledger
        .light_nodes(ctx.plan, light)
        .map(|c| Sample {
            omega_i: c.omega_i,
            omega_o: c.omega_o,
            value: c.xyz,
        })
        .collect();
    Resampler::slice(&samples, &omega_i, &ResampleSpec::default()).map_err(|e| e.to_string())
}

fn score_interpolated(
    ctx: &Ctx,
    p: &PendingPartner,
    slice: &Result<Resampler, String>,
    t: f64,
) -> PairRecord {
    let c = &p.capture;
    let light_dir = ctx.plan.directions()[p.light].spherical().to_vector();
    // the mirrored pose: the lamp where this capture's camera was, the camera where its lamp was
    let mismatch = angle_between(&light_dir, &c.omega_o).to_degrees();
    let mut rec = PairRecord {
        a: c.idx,
        b: c.idx,
        entries: [p.entry, p.entry],
        status: PairStatus::Unresolved,
        mismatch_deg: mismatch,
        t,
        xyz_a: None,
        xyz_b: None,
        diff: None,
        by_command: c.by_command,
        interpolated: None,
    };
    let mut info = Interpolation {
        light: p.light,
        method: String::new(),
        nodes: 0,
        spread_xyz: None,
        sigma_de2000: None,
        error: None,
    };
    let resampled = match slice {
        Ok(r) => {
            info.method = r.method_name().into();
            info.nodes = r.nodes();
            r.at(&light_dir, &c.omega_i).map_err(|e| e.to_string())
        }
        Err(e) => Err(e.clone()),
    };
    match resampled {
        Err(e) => info.error = Some(e),
        Ok(v) => {
            let theta_l = Spherical::from_vector(&light_dir).theta_deg();
            match pair_residual(
                c.xyz,
                c.theta_i_deg,
                v.value,
                theta_l,
                ctx.colour.white,
                ctx.colour.min_cos,
            ) {
                Ok(r) => {
                    // the spread in the units of the re-corrected partner (xyz_b): the cosine
                    // re-correction scales the partner by one factor
                    let f = if v.value[1] > 0.0 {
                        r.xyz2[1] / v.value[1]
                    } else {
                        1.0
                    };
                    let spread = [f * v.spread[0], f * v.spread[1], f * v.spread[2]];
                    let moved = [
                        r.xyz2[0] + spread[0],
                        r.xyz2[1] + spread[1],
                        r.xyz2[2] + spread[2],
                    ];
                    info.spread_xyz = Some(spread);
                    info.sigma_de2000 =
                        Some(colour_difference(r.xyz2, moved, ctx.colour.white).de2000);
                    rec.xyz_a = Some(r.xyz1);
                    rec.xyz_b = Some(r.xyz2);
                    rec.diff = Some(r.diff);
                    rec.status = PairStatus::Interpolated;
                }
                Err(e) => {
                    rec.status = match e {
                        PairError::Grazing { .. } => PairStatus::Grazing,
                        _ => PairStatus::Unresolved,
                    };
                    info.error = Some(e.to_string());
                }
            }
        }
    }
    rec.interpolated = Some(info);
    rec
}
