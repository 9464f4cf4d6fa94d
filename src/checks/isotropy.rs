//! The isotropy stage (isotropic samples only): each capture at its exact pose against the mean
//! of the earlier members of its class, the same (θi, θo, |φi − φo|) at other azimuths, after the
//! cosine re-correction to the class's nominal angles. Its running means are the summary's
//! isotropy table.

use super::records::{IsotropyRecord, Table2};
use super::{Checked, Ctx};
use crate::measure::colour::colour_difference;
use crate::measure::plan::IsotropyKey;
use std::collections::HashMap;

#[derive(Debug, Clone, Default)]
struct ClassMean {
    n: usize,
    sum: [f64; 3],
}

#[derive(Debug, Clone, Default)]
pub(super) struct IsotropyStage {
    classes: HashMap<IsotropyKey, ClassMean>,
    pub(super) table: Table2,
    pub(super) comparisons: u64,
}

impl IsotropyStage {
    /// Compare a capture with its class and join it. None for the first member of a class, a
    /// capture outside the plan, or one too grazing to re-correct.
    pub(super) fn add(
        &mut self,
        ctx: &Ctx,
        entry: usize,
        capture: &Checked,
    ) -> Option<IsotropyRecord> {
        let e = ctx.plan.entry(entry).ok()?;
        let key = ctx.plan.isotropy_key(&e);
        let c_lo = (key.theta_lo_mdeg as f64 / 1000.0).to_radians().cos();
        let c_hi = (key.theta_hi_mdeg as f64 / 1000.0).to_radians().cos();
        let ci = capture.theta_i_deg.to_radians().cos();
        if !(ci >= ctx.colour.min_cos && c_lo * c_hi > 0.0) {
            return None;
        }
        let f = (c_lo * c_hi).sqrt() / ci;
        let xyz = capture.xyz;
        let v = [xyz[0] * f, xyz[1] * f, xyz[2] * f];
        let acc = self.classes.entry(key).or_default();
        let mut record = None;
        if acc.n > 0 {
            let n = acc.n as f64;
            let mean = [acc.sum[0] / n, acc.sum[1] / n, acc.sum[2] / n];
            let diff = colour_difference(mean, v, ctx.colour.white);
            self.table.add(&diff);
            self.comparisons += 1;
            record = Some(IsotropyRecord {
                idx: capture.idx,
                entry,
                class: [
                    key.theta_lo_mdeg as f64 / 1000.0,
                    key.theta_hi_mdeg as f64 / 1000.0,
                    key.dphi_mdeg as f64 / 1000.0,
                ],
                earlier_members: acc.n,
                diff,
            });
        }
        acc.n += 1;
        for c in 0..3 {
            acc.sum[c] += v[c];
        }
        record
    }
}
