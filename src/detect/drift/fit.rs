//! The drift model's fit: the design of gain, steps, per-bucket non-reciprocity and the
//! off-centre mount's pattern, solved by iteratively reweighted least squares.

use super::*;

impl DriftDetector {
    /// The rate alarm after a refit to `est`: raised when the rate is significant and beyond
    /// the tolerance (once the mount's light half is told apart from it), cleared with
    /// hysteresis.
    pub(super) fn rate_events(&mut self, est: DriftEstimate) -> Vec<DriftEvent> {
        let (r, se, tol, z) = (
            est.rate_pct_per_h,
            est.se_pct_per_h,
            self.spec.rate_tolerance_pct_per_h,
            self.spec.z,
        );
        if !self.rate_alarms {
            return Vec::new();
        }
        let identified = self.mount.is_none() || self.light_separated;
        if !self.rate_alarm && identified && rate_alarm_raised(r, se, tol, z) {
            match self.pattern_verdict(est) {
                PatternVerdict::Confirmed => {
                    self.rate_alarm = true;
                    vec![DriftEvent::RateSignificant(est)]
                }
                PatternVerdict::Unresolved(robust) if !self.unresolved_said => {
                    self.unresolved_said = true;
                    vec![DriftEvent::Unresolved {
                        estimate: est,
                        robust,
                    }]
                }
                PatternVerdict::Unresolved(_) | PatternVerdict::NotYet => Vec::new(),
            }
        } else if self.rate_alarm && rate_alarm_cleared(r, se, tol, z) {
            self.rate_alarm = false;
            vec![DriftEvent::RateCleared(est)]
        } else {
            Vec::new()
        }
    }

    /// Whether a rate the model finds significant (`est`) stays so beside a stationary
    /// light-side pattern: any smooth function of the light's direction in the sample frame,
    /// here its first `PATTERN_HARMONICS` azimuthal harmonics with free amplitudes in every
    /// θi layer (`fit_design`'s `layer_pattern`). In light-outer order such a pattern and a
    /// drift both move with time within a layer; they are told apart where the light returns
    /// to its first azimuths late in the layer (a drift does not return) and by a drift's
    /// one rate across layers. The robust fit costs O(n·p²) with p about 25, so it is run at
    /// most every `PATTERN_CHECK_EVERY` pairs and its verdict kept in between.
    fn pattern_verdict(&mut self, est: DriftEstimate) -> PatternVerdict {
        if !self.spec.pattern_check {
            return PatternVerdict::Confirmed;
        }
        let n = self.obs.len();
        if let Some((at, false)) = self.pattern_checked {
            if n < at + PATTERN_CHECK_EVERY {
                return PatternVerdict::NotYet;
            }
        }
        let Some(f) = self.fit_design(self.mount.is_some(), true) else {
            self.pattern_checked = Some((n, false));
            return PatternVerdict::NotYet;
        };
        let robust = f.estimate;
        let (tol, z) = (self.spec.rate_tolerance_pct_per_h, self.spec.z);
        let confirmed = robust.rate_pct_per_h * est.rate_pct_per_h > 0.0
            && rate_alarm_raised(robust.rate_pct_per_h, robust.se_pct_per_h, tol, z);
        self.pattern_checked = Some((n, confirmed));
        if confirmed {
            PatternVerdict::Confirmed
        } else {
            PatternVerdict::Unresolved(robust)
        }
    }

    /// Adopts a design fit: its bucket effects, scales, steps and mount pattern.
    pub(super) fn keep(&mut self, f: DesignFit) -> DriftEstimate {
        self.beta = f.beta;
        self.bucket_scale = f.bucket_scale;
        self.step_effects = f.step_effects;
        if let Some(m) = f.mount {
            self.mount = Some(m);
            self.light_separated |= m.light_separated();
        }
        f.estimate
    }

    /// While the mount terms are out of the model: whether the camera side of the pattern is
    /// now significant and large enough to bring them in. The camera's half is fitted within
    /// each light sweep, so a gain drift or step cannot pose as it; the light's half can, and
    /// is not tested.
    pub(super) fn mount_found(&self) -> Option<DesignFit> {
        if !self.spec.mount_terms || self.mount.is_some() {
            return None;
        }
        let f = self.fit_design(true, false)?;
        let m = f.mount?;
        let (amp, _) = m.camera_pct();
        let lower = amp - self.spec.z * 100.0 * m.camera_se;
        (m.camera_se.is_finite() && lower > self.spec.mount_min_pct).then_some(f)
    }

    /// The off-centre mount's pattern, once it is part of the model.
    pub(crate) fn mount(&self) -> Option<MountPattern> {
        self.mount
    }

    /// IRLS with Huber weights and bucket fixed effects (within-bucket centring).
    pub(super) fn fit(&mut self) -> Option<DriftEstimate> {
        if self.mount.is_some() || !self.step_times.is_empty() {
            let f = self.fit_design(self.mount.is_some(), false)?;
            return Some(self.keep(f));
        }
        let n = self.obs.len();
        // precision weights from each observation's own uncertainty (equal in the first pass)
        let mut w: Vec<f64> = self.obs.iter().map(|o| prior_weight(0.0, o)).collect();
        let buckets = self.index.buckets();
        let mut r = 0.0;
        let mut beta: Vec<(f64, usize)> = Vec::new();
        let mut scale = 0.0;
        let mut res: Vec<f64> = Vec::new();
        let mut se = f64::INFINITY;
        for _ in 0..5 {
            // weighted bucket means of Δt and d
            let mut acc = vec![(0.0, 0.0, 0.0, 0usize); buckets.keys.len()];
            for ((o, wi), &b) in self.obs.iter().zip(&w).zip(&buckets.of) {
                let e = &mut acc[b];
                e.0 += wi;
                e.1 += wi * (o.t_b_h - o.t_a_h);
                e.2 += wi * o.d;
                e.3 += 1;
            }
            // the bucket means (a bucket whose every observation has zero weight adds nothing)
            let means: Vec<Option<(f64, f64)>> = acc
                .iter()
                .map(|&(sw, sx, sy, _)| (sw > 0.0).then(|| (sx / sw, sy / sw)))
                .collect();
            let (mut sxx, mut sxy) = (0.0, 0.0);
            for ((o, wi), &b) in self.obs.iter().zip(&w).zip(&buckets.of) {
                let Some((mx, my)) = means[b] else {
                    continue;
                };
                let x = (o.t_b_h - o.t_a_h) - mx;
                let y = o.d - my;
                sxx += wi * x * x;
                sxy += wi * x * y;
            }
            if !(sxx > 1e-12) {
                return None;
            }
            r = sxy / sxx;
            beta = acc
                .iter()
                .map(|(sw, sx, sy, nb)| ((sy - r * sx) / sw, *nb))
                .collect();
            res = self
                .obs
                .iter()
                .zip(&buckets.of)
                .map(|(o, &b)| o.d - r * (o.t_b_h - o.t_a_h) - beta[b].0)
                .collect();
            scale = huber_reweight(&res, &self.obs, &mut w);
            // variance of r: σ² / Sxx with the weighted residual variance
            let dof = (n as f64 - beta.len() as f64 - 1.0).max(1.0);
            let sse: f64 = res.iter().zip(&w).map(|(e, wi)| wi * e * e).sum();
            se = ((sse / dof).max(self.spec.scale_floor.powi(2)) / sxx).sqrt();
        }
        self.bucket_scale = bucket_scales(&buckets, &res);
        self.beta = buckets.map(&beta);
        Some(DriftEstimate {
            pairs: n,
            rate_pct_per_h: 100.0 * r,
            se_pct_per_h: 100.0 * se,
            residual_scale: scale,
        })
    }

    /// The same IRLS with one indicator column per known step (a pair spanning τ_k carries
    /// s_k) and, with `mount`, the four mount columns: the centred weighted design solved by
    /// normal equations and their pseudo-inverse, which is also the covariance. With
    /// `layer_pattern`, the light-side pattern's columns follow (`pattern_layers`).
    /// Deterministic: fixed passes, buckets in BTreeMap order. Pure: the caller decides whether
    /// to keep the result.
    /// The design, flat: row i is `rows[i * p..(i + 1) * p]`: the time between the pair's
    /// captures, a 1 for each step between them, the mount columns, and per pattern layer the
    /// later capture's cos kφ, sin kφ less the earlier one's (k = 1..`PATTERN_HARMONICS`; 0
    /// outside the pair's layer).
    pub(super) fn design_rows(&self, mount: bool, layers: &[i64], p: usize) -> Vec<f64> {
        let mut rows: Vec<f64> = Vec::with_capacity(self.obs.len() * p);
        for o in &self.obs {
            rows.push(o.t_b_h - o.t_a_h);
            for &tau in &self.step_times {
                rows.push(if o.t_a_h < tau && tau <= o.t_b_h {
                    1.0
                } else {
                    0.0
                });
            }
            if mount {
                rows.extend_from_slice(&o.mount);
            }
            for &layer in layers {
                for k in 1..=PATTERN_HARMONICS {
                    let kf = k as f64;
                    let (a, b) = (kf * o.light_az[0], kf * o.light_az[1]);
                    if o.bucket.0 == layer {
                        rows.push(b.cos() - a.cos());
                        rows.push(b.sin() - a.sin());
                    } else {
                        rows.push(0.0);
                        rows.push(0.0);
                    }
                }
            }
        }
        rows
    }

    /// The θi layers (the buckets' light θ) whose pairs span more than one light azimuth:
    /// each gets the pattern's columns.
    pub(super) fn pattern_layers(&self) -> Vec<i64> {
        let mut layers: Vec<i64> = self
            .obs
            .iter()
            .filter(|o| (o.light_az[1] - o.light_az[0]).abs() > 1e-9)
            .map(|o| o.bucket.0)
            .collect();
        layers.sort_unstable();
        layers.dedup();
        layers
    }

    pub(super) fn fit_design(&self, mount: bool, layer_pattern: bool) -> Option<DesignFit> {
        let n = self.obs.len();
        let k = self.step_times.len();
        let layers = if layer_pattern {
            self.pattern_layers()
        } else {
            Vec::new()
        };
        let p = 1 + k + if mount { 4 } else { 0 } + 2 * PATTERN_HARMONICS * layers.len();
        let rows = self.design_rows(mount, &layers, p);
        let mut w: Vec<f64> = self.obs.iter().map(|o| prior_weight(0.0, o)).collect();
        let buckets = self.index.buckets();
        let nk = buckets.keys.len();
        let mut coef = DVector::<f64>::zeros(p);
        let mut cov = DMatrix::<f64>::zeros(p, p);
        let mut beta: Vec<(f64, usize)> = Vec::new();
        let mut scale = 0.0;
        let mut res: Vec<f64> = Vec::new();
        let mut inflation = 1.0;
        let mut sums = BucketSums::new(nk, p);
        for _ in 0..5 {
            sums.accumulate(&self.obs, &rows, &w, &buckets.of);
            let (acc_w, acc_x, acc_y, acc_n) = (&sums.w, &sums.x, &sums.y, &sums.n);
            let (ata, atb) = sums.normal_equations(&self.obs, &rows, &w, &buckets.of);
            // a step no pair spans yet has a zero column: the pseudo-inverse leaves its
            // coefficient at zero and its variance out
            let pinv = ata.clone().pseudo_inverse(1e-12).ok()?;
            coef = &pinv * &atb;
            if !coef.iter().all(|c| c.is_finite()) {
                return None;
            }
            beta = (0..nk)
                .map(|b| {
                    let sx = &acc_x[b * p..(b + 1) * p];
                    let fx: f64 = (0..p).map(|j| coef[j] * sx[j]).sum();
                    ((acc_y[b] - fx) / acc_w[b], acc_n[b])
                })
                .collect();
            res = self
                .obs
                .iter()
                .zip(rows.chunks_exact(p))
                .zip(&buckets.of)
                .map(|((o, x), &b)| o.d - (0..p).map(|j| coef[j] * x[j]).sum::<f64>() - beta[b].0)
                .collect();
            scale = huber_reweight(&res, &self.obs, &mut w);
            let dof = (n as f64 - beta.len() as f64 - p as f64).max(1.0);
            let sse: f64 = res.iter().zip(&w).map(|(e, wi)| wi * e * e).sum();
            // v · sse / dof in that order, as without a floor: the fits replay to the bit
            let floor = self.spec.scale_floor.powi(2);
            let scaled = |v: f64| {
                if floor > sse / dof {
                    v * floor
                } else {
                    v * sse / dof
                }
            };
            cov = pinv.map(scaled);
            if mount {
                // the rate's variance with the light's two mount columns left out
                let keep: Vec<usize> = (0..p).filter(|&j| j != 1 + k && j != 2 + k).collect();
                let sub = ata.select_rows(keep.iter()).select_columns(keep.iter());
                let v0 = scaled(sub.pseudo_inverse(1e-12).ok()?[(0, 0)]);
                inflation = (cov[(0, 0)] / v0).max(0.0).sqrt();
            }
        }
        let step_effects = self
            .step_times
            .iter()
            .enumerate()
            // a step no pair spans yet (a zero column) is not estimable: left out until it is
            .filter(|(j, _)| cov[(1 + j, 1 + j)] > 0.0 && cov[(1 + j, 1 + j)].is_finite())
            .map(|(j, &t_h)| StepEffect {
                t_h,
                ln_size: coef[1 + j],
                se: cov[(1 + j, 1 + j)].sqrt(),
            })
            .collect();
        let mount = mount.then(|| {
            let m = 1 + k;
            let se = |a: usize, b: usize| cov[(a, a)].max(cov[(b, b)]).max(0.0).sqrt();
            MountPattern {
                light: [coef[m], coef[m + 1]],
                light_se: se(m, m + 1),
                camera: [coef[m + 2], coef[m + 3]],
                camera_se: se(m + 2, m + 3),
                rate_inflation: inflation,
            }
        });
        Some(DesignFit {
            estimate: DriftEstimate {
                pairs: n,
                rate_pct_per_h: 100.0 * coef[0],
                se_pct_per_h: 100.0 * cov[(0, 0)].max(0.0).sqrt(),
                residual_scale: scale,
            },
            beta: buckets.map(&beta),
            bucket_scale: bucket_scales(&buckets, &res),
            step_effects,
            mount,
        })
    }
}

/// An observation's weight from its own σ relative to the residual scale: 1 / (1 + (σ/scale)²).
/// (`add` admits only finite σ ≥ 0; the floor keeps every bucket's weight positive.)
pub(super) fn prior_weight(scale: f64, o: &PairObservation) -> f64 {
    if o.sigma > 0.0 && scale > 0.0 {
        (1.0 / (1.0 + (o.sigma / scale).powi(2))).max(1e-12)
    } else {
        1.0
    }
}

/// One IRLS reweighting: the residuals' robust scale (MAD), then Huber weights (c = 1.345 of
/// it) times each observation's prior weight. Returns the scale.
pub(super) fn huber_reweight(res: &[f64], obs: &[PairObservation], w: &mut [f64]) -> f64 {
    let mut scale = robust_scale_upper(res);
    if !(scale > 0.0) {
        scale = 1e-9;
    }
    let c = 1.345 * scale;
    for ((wi, e), o) in w.iter_mut().zip(res).zip(obs) {
        *wi = prior_weight(scale, o) * if e.abs() <= c { 1.0 } else { c / e.abs() };
    }
    scale
}

/// The robust scale (MAD) of the final residuals per geometry bucket.
pub(super) fn bucket_scales(buckets: &Buckets, res: &[f64]) -> BTreeMap<(i64, i64), f64> {
    let mut per: Vec<Vec<f64>> = vec![Vec::new(); buckets.keys.len()];
    for (&b, e) in buckets.of.iter().zip(res) {
        per[b].push(e.abs());
    }
    buckets
        .keys
        .iter()
        .zip(per)
        .map(|(k, v)| (*k, robust_scale_upper(&v)))
        .collect()
}

/// The observations' geometry buckets as dense indices, numbered in key order: a fit's
/// per-bucket sums are then vectors, visited in the order a map keyed by bucket would visit
/// them, and every sum is taken in the same order as before (the fits replay to the bit).
pub(super) struct Buckets {
    /// The buckets, in key order.
    keys: Vec<(i64, i64)>,
    /// Each observation's bucket: an index into `keys`.
    of: Vec<usize>,
}

/// The geometry buckets seen so far, kept beside the observations: each bucket gets an id when
/// first seen, each observation carries its bucket's id, and a fit's `Buckets` (key-order
/// indices) come from a rank table without a tree lookup per observation.
#[derive(Debug, Clone, Default)]
pub(super) struct BucketIndex {
    ids: BTreeMap<(i64, i64), usize>,
    /// Each observation's bucket id (parallel to `DriftDetector::obs`).
    of_id: Vec<usize>,
}

impl BucketIndex {
    pub(super) fn push(&mut self, bucket: (i64, i64)) {
        let next = self.ids.len();
        let id = *self.ids.entry(bucket).or_insert(next);
        self.of_id.push(id);
    }

    /// The index of exactly `obs` (after observations were taken out).
    pub(super) fn rebuild(obs: &[PairObservation]) -> BucketIndex {
        let mut b = BucketIndex::default();
        for o in obs {
            b.push(o.bucket);
        }
        b
    }

    pub(super) fn buckets(&self) -> Buckets {
        let mut rank = vec![0usize; self.ids.len()];
        let mut keys = Vec::with_capacity(self.ids.len());
        for (pos, (k, &id)) in self.ids.iter().enumerate() {
            rank[id] = pos;
            keys.push(*k);
        }
        Buckets {
            keys,
            of: self.of_id.iter().map(|&id| rank[id]).collect(),
        }
    }
}

impl Buckets {
    /// The bucket effects as the map the detector keeps.
    pub(super) fn map<T: Copy>(&self, values: &[T]) -> BTreeMap<(i64, i64), T> {
        self.keys
            .iter()
            .copied()
            .zip(values.iter().copied())
            .collect()
    }
}

/// Azimuthal harmonics of the light-side pattern per θi layer in the pattern-robust fit: the
/// first two, as the light sweeps' layer model has (a footprint's and an outline's lowest
/// orders); a layer of 6 lights (θi = 15° on the UBO plan) is then fitted almost exactly, and
/// its trend left to the layers with more lights.
pub(super) const PATTERN_HARMONICS: usize = 2;

/// The pattern-robust fit is redone at most this often (pairs) while it does not confirm.
pub(super) const PATTERN_CHECK_EVERY: usize = 100;

/// What the pattern-robust fit says of a significant rate.
pub(super) enum PatternVerdict {
    /// Significant beside the pattern too (or no check asked for).
    Confirmed,
    /// Not significant beside it: the robust fit.
    Unresolved(DriftEstimate),
    /// Not checked again yet after a fit that did not confirm.
    NotYet,
}

/// What `fit_design` found.
pub(super) struct DesignFit {
    estimate: DriftEstimate,
    beta: BTreeMap<(i64, i64), (f64, usize)>,
    bucket_scale: BTreeMap<(i64, i64), f64>,
    step_effects: Vec<StepEffect>,
    mount: Option<MountPattern>,
}

/// Per bucket: the sum of weights, the weighted sums of each design column (flat, `p` a
/// bucket) and of d, and the count.
pub(super) struct BucketSums {
    p: usize,
    w: Vec<f64>,
    x: Vec<f64>,
    y: Vec<f64>,
    n: Vec<usize>,
}

impl BucketSums {
    pub(super) fn new(nk: usize, p: usize) -> Self {
        BucketSums {
            p,
            w: vec![0.0; nk],
            x: vec![0.0; nk * p],
            y: vec![0.0; nk],
            n: vec![0; nk],
        }
    }

    /// The weighted bucket sums of every column and of d, anew.
    pub(super) fn accumulate(
        &mut self,
        obs: &[PairObservation],
        rows: &[f64],
        w: &[f64],
        of: &[usize],
    ) {
        let p = self.p;
        self.w.fill(0.0);
        self.x.fill(0.0);
        self.y.fill(0.0);
        self.n.fill(0);
        for (((o, x), wi), &b) in obs.iter().zip(rows.chunks_exact(p)).zip(w).zip(of) {
            self.w[b] += wi;
            let sx = &mut self.x[b * p..(b + 1) * p];
            for j in 0..p {
                sx[j] += wi * x[j];
            }
            self.y[b] += wi * o.d;
            self.n[b] += 1;
        }
    }

    /// The normal equations of the design centred on its bucket means, weighted.
    pub(super) fn normal_equations(
        &self,
        obs: &[PairObservation],
        rows: &[f64],
        w: &[f64],
        of: &[usize],
    ) -> (DMatrix<f64>, DVector<f64>) {
        let (p, nk) = (self.p, self.w.len());
        let (acc_w, acc_x, acc_y) = (&self.w, &self.x, &self.y);
        // the normal equations of the centred, weighted design, accumulated row by row:
        // p is at most a few columns, so this costs O(n·p²) without an n × p matrix
        let mut ata_flat = vec![0.0; p * p];
        let mut atb_flat = vec![0.0; p];
        let mut xc = vec![0.0; p];
        // the bucket means of every column and of d (a bucket whose every observation has
        // zero weight adds nothing)
        let live: Vec<bool> = acc_w.iter().map(|&sw| sw > 0.0).collect();
        let mean_x: Vec<f64> = (0..nk * p).map(|i| acc_x[i] / acc_w[i / p]).collect();
        let mean_y: Vec<f64> = (0..nk).map(|b| acc_y[b] / acc_w[b]).collect();
        for (((o, x), wi), &b) in obs.iter().zip(rows.chunks_exact(p)).zip(w).zip(of) {
            if !live[b] {
                continue;
            }
            let mx = &mean_x[b * p..(b + 1) * p];
            for j in 0..p {
                xc[j] = x[j] - mx[j];
            }
            let yc = o.d - mean_y[b];
            for j in 0..p {
                // (wi·xc_j)·… is how `wi * xc[j] * x` groups: the same products as before
                let wx = wi * xc[j];
                atb_flat[j] += wx * yc;
                let row = &mut ata_flat[j * p..j * p + j + 1];
                for (a, x) in row.iter_mut().zip(&xc[..=j]) {
                    *a += wx * x;
                }
            }
        }
        let mut ata =
            DMatrix::<f64>::from_fn(p, p, |j, l| if l <= j { ata_flat[j * p + l] } else { 0.0 });
        let atb = DVector::<f64>::from_column_slice(&atb_flat);
        for j in 0..p {
            for l in 0..j {
                ata[(l, j)] = ata[(j, l)];
            }
        }
        (ata, atb)
    }
}
