//! The reference the sweeps are judged against: the back-fit of class, light and camera
//! effects, the interpolant and the smooth model of the effects, the sensitivities to the
//! joints, the layer's azimuthal level pattern and the sweeps' pattern fits.

use super::*;

/// The F + L + C reference: class, light and camera effects (ln units), and which classes have
/// members.
pub(super) struct Reference {
    pub(super) class: Vec<f64>,
    pub(super) light: Vec<f64>,
    pub(super) camera: Vec<f64>,
    pub(super) seen: Vec<bool>,
}

impl Reference {
    /// The class effects, NaN for classes without an earlier member.
    pub(super) fn class_effects(&self) -> Vec<f64> {
        self.class
            .iter()
            .zip(&self.seen)
            .map(|(v, s)| if *s { *v } else { f64::NAN })
            .collect()
    }
}

/// One capture's row of the pattern fits: its residual against the reference, its
/// sensitivities to joint 1, joint 2 and the wagon (NaN where there is none), and the
/// wagon's last direction of motion.
#[derive(Debug, Clone, Copy)]
pub(super) struct Row {
    pub(super) e: f64,
    pub(super) s: [f64; 3],
    pub(super) wagon_dir: f64,
}

impl Row {
    /// The joints' columns (detection).
    pub(super) fn joints(&self) -> (f64, [f64; 2]) {
        (self.e, [self.s[0], self.s[1]])
    }

    /// The joints', the wagon's, and the wagon's signed by its direction of motion (a lag b
    /// against it adds b times that column): a slip's size. None without the wagon's.
    pub(super) fn with_wagon(&self) -> Option<(f64, [f64; 4])> {
        let w = self.s[2];
        w.is_finite()
            .then_some((self.e, [self.s[0], self.s[1], w, -self.wagon_dir * w]))
    }
}

/// Where a sensitivity comes from: the interpolant through the classes' effects, or the
/// smooth least-squares model of them (`smooth_brdf`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Model {
    Interpolant,
    Smooth,
}

/// A sweep's pattern fit: coefficients [λ, b₁, …], residual variance, (XᵀX)⁻¹ when the fit is
/// well conditioned.
pub(super) struct PatternFit {
    pub(super) beta: DVector<f64>,
    pub(super) sigma2: f64,
    pub(super) inv: Option<DMatrix<f64>>,
}

impl PatternFit {
    /// The standard error of coefficient `j`.
    pub(super) fn se(&self, j: usize) -> Option<f64> {
        self.inv
            .as_ref()
            .map(|m| (self.sigma2 * m[(j, j)]).max(0.0).sqrt())
    }
}

pub(super) fn group_means(values: &[f64], groups: &[usize], n: usize) -> Vec<f64> {
    let mut sum = vec![0.0; n];
    let mut count = vec![0usize; n];
    for (v, g) in values.iter().zip(groups) {
        sum[*g] += v;
        count[*g] += 1;
    }
    sum.iter()
        .zip(&count)
        .map(|(s, c)| if *c > 0 { s / *c as f64 } else { 0.0 })
        .collect()
}

/// A capture's sensitivity beyond this many robust scales of its sweep's is left out of the fit.
pub(super) const LEVERAGE_CAP: f64 = 6.0;

/// A slip's size is taken from the smooth model's fit of a sweep only when its standard error
/// is at most this (degrees; twice the joint tolerance); a looser fit falls back to the
/// interpolant's.
pub(super) const SMOOTH_SE_MAX_DEG: f64 = 0.5;

/// A level crossing is the tilt's, not the lamp's, when the smooth model's offset of a joint
/// over the crossing's sweeps departs from its earlier sweeps' by this many standard
/// deviations (one-sided normal tail 0.13 %), in the direction that explains the level, and
/// by at least the joint tolerance. The deviation counts the earlier sweeps' spread as one
/// shared offset, not as noise that averages out: a layer's nuisance moves consecutive sweeps
/// alike.
pub(super) const ATTRIBUTION_Z: f64 = 3.0;

/// Residual trimming of the per-sweep fit: passes, and the cut in robust residual scales.
pub(super) const TRIM_PASSES: usize = 2;
pub(super) const TRIM_SCALES: f64 = 3.0;

/// Earlier lights of a θi layer before its level pattern is fitted: the 4th harmonic (with a
/// constant: 3 coefficients), then the 2nd as well (5).
pub(super) const PATTERN_MIN_LIGHTS: [usize; 2] = [6, 10];

/// A θi layer's level pattern at the current light (`SweepMonitor::expected_level`): the level
/// it predicts, the prediction's standard deviation, and its model's columns beyond the
/// constant (their count changes when a harmonic enters or the borrowed 2nd harmonic enters or
/// leaves).
#[derive(Debug, Clone)]
pub(super) struct LayerPattern {
    pub(super) level: f64,
    pub(super) sd: f64,
    pub(super) columns: PatternColumns,
    /// The earlier lights' residuals about the fit, widened by √(n / (n − p)) to stand for
    /// out-of-sample ones: a layer's scale history restarts from them when its model grows.
    pub(super) residuals: Vec<f64>,
}

/// A level pattern's columns beyond the constant: a (cos, sin) pair per harmonic, and the
/// borrowed 2nd harmonic of a phase ((cos 2φ, sin 2φ) weights) as one column.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(super) struct PatternColumns {
    harmonics: [f64; 2],
    len: usize,
    pub(super) borrowed: Option<[f64; 2]>,
}

impl PatternColumns {
    /// The columns of `harmonics` (at most the first two: the level pattern fits the 4th and
    /// the 2nd) and `borrowed`.
    pub(super) fn new(harmonics: &[f64], borrowed: Option<[f64; 2]>) -> Self {
        let mut c = Self {
            borrowed,
            ..Self::default()
        };
        for h in harmonics.iter().take(2) {
            c.harmonics[c.len] = *h;
            c.len += 1;
        }
        c
    }

    pub(super) fn harmonics(&self) -> &[f64] {
        &self.harmonics[..self.len]
    }

    /// The number of columns with the constant.
    pub(super) fn count(&self) -> usize {
        1 + 2 * self.len + usize::from(self.borrowed.is_some())
    }
}

/// The layer below lends its 2nd harmonic's phase only when its amplitude is this many
/// standard errors from zero, and only to a layer whose 4th harmonic is as clear.
pub(super) const BORROW_SIGMAS: f64 = 3.0;

/// The amplitude of a (cos, sin) coefficient pair in units of its standard error along its
/// own direction, from the coefficients `b` and their covariance `cov` (columns `i`, `i + 1`).
/// 0 for a zero amplitude or a zero or non-finite variance (an exact fit has no phase to lend).
pub(super) fn amplitude_t(b: &DVector<f64>, cov: &DMatrix<f64>, i: usize) -> f64 {
    let (c, s) = (b[i], b[i + 1]);
    let a = c.hypot(s);
    if !(a > 0.0 && a.is_finite()) {
        return 0.0;
    }
    let u = [c / a, s / a];
    let var = u[0] * u[0] * cov[(i, i)]
        + 2.0 * u[0] * u[1] * cov[(i, i + 1)]
        + u[1] * u[1] * cov[(i + 1, i + 1)];
    if !(var > 0.0 && var.is_finite()) {
        return 0.0;
    }
    a / var.sqrt()
}

/// A layer's level pattern fit: the pattern, the coefficients and their covariance.
pub(super) struct LevelPatternFit {
    pub(super) pattern: LayerPattern,
    pub(super) coef: DVector<f64>,
    cov: DMatrix<f64>,
}

/// A row of the level pattern's design at azimuth `p`: the constant, a (cos, sin) pair per
/// harmonic, and with `borrowed` the 2nd harmonic of that phase.
pub(super) fn pattern_row(p: f64, harmonics: &[f64], borrowed: Option<[f64; 2]>) -> Vec<f64> {
    let mut v = vec![1.0];
    for h in harmonics {
        v.push((h * p).cos());
        v.push((h * p).sin());
    }
    if let Some(u) = borrowed {
        v.push(u[0] * (2.0 * p).cos() + u[1] * (2.0 * p).sin());
    }
    v
}

/// A layer's level pattern at azimuth `here` from its earlier lights' levels `values` at
/// `azimuths`: least squares on a constant, `harmonics` (cos and sin columns each), and with
/// `borrowed` a 2nd harmonic of that phase ((cos 2φ, sin 2φ) weights) as the last column.
pub(super) fn pattern_fit(
    azimuths: &[f64],
    values: &[f64],
    harmonics: &[f64],
    borrowed: Option<[f64; 2]>,
    here: f64,
) -> Option<LevelPatternFit> {
    let row = |p: f64| pattern_row(p, harmonics, borrowed);
    let (n, cols) = (
        azimuths.len(),
        1 + 2 * harmonics.len() + borrowed.is_some() as usize,
    );
    if n <= cols || values.len() != n {
        return None;
    }
    let rows: Vec<Vec<f64>> = azimuths.iter().map(|&p| row(p)).collect();
    let x = DMatrix::from_fn(n, cols, |i, j| rows[i][j]);
    let y = DVector::from_column_slice(values);
    let b = x.clone().svd(true, true).solve(&y, 1e-9).ok()?;
    let x0 = DVector::from_vec(row(here));
    let level = x0.dot(&b);
    // the prediction's standard deviation: σ²·(1 + x₀ᵀ(XᵀX)⁻¹x₀)
    let resid = &y - &x * &b;
    let sigma2 = resid.norm_squared() / (n - cols).max(1) as f64;
    let widen = (n as f64 / (n - cols).max(1) as f64).sqrt();
    let inv = (x.transpose() * &x).pseudo_inverse(1e-12).ok()?;
    let sd = (sigma2 * (1.0 + (x0.transpose() * &inv * &x0)[(0, 0)]))
        .max(0.0)
        .sqrt();
    (level.is_finite() && sd.is_finite()).then(|| LevelPatternFit {
        pattern: LayerPattern {
            level,
            sd,
            columns: PatternColumns::new(harmonics, borrowed),
            residuals: resid.iter().map(|e| e * widen).collect(),
        },
        cov: inv * sigma2,
        coef: b,
    })
}

/// A harmonic is fitted only where the layer's lights sample its period at least this often
/// (the 4th at azimuth steps of 22.5° and less, θi ≥ 45° on the UBO plan; the 2nd at 45°).
pub(super) const PATTERN_SAMPLES_PER_PERIOD: f64 = 4.0;

/// Back-fitting iterations of the F + L + C reference (converged to < 1e-4 by 30 on UBO runs).
pub(super) const BACKFIT_ITERATIONS: usize = 30;

impl SweepMonitor {
    /// The interpolant of BRDF-like values (Y / cos θi), rebuilt when the data grew by a
    /// quarter or the current layer doubled. `class_effect` is the F of the back-fit (ln units,
    /// per class id; NaN where a class has no earlier member): each class is one node at its
    /// first member's directions, free of the per-light and per-camera effects (raw captures as
    /// nodes carry those effects into the sensitivities). No reciprocal swaps: F(θi, θo) keeps
    /// the θi-dependent part of the lamp footprint, so a swapped node can be off by tens of per
    /// cent at grazing light.
    pub(super) fn ensure_model(&mut self, layer: i64, class_effect: &[f64]) {
        let total = self.captures.len();
        let here = self.layer_count(layer);
        let built_here = self.model_layer_counts.get(&layer).copied().unwrap_or(0);
        let stale = self.model.is_none()
            || total as f64 >= 1.25 * self.model_built_with as f64
            || here >= 2 * built_here.max(1);
        if !stale {
            return;
        }
        let mut samples = Vec::with_capacity(self.class_first.len());
        let mut nodes = Vec::with_capacity(self.class_first.len());
        for (&k, fx) in self.class_first.iter().zip(class_effect) {
            if !fx.is_finite() {
                continue;
            }
            let y = fx.exp();
            let c = &self.captures[k];
            let ci = c.omega_i.z;
            if ci <= 1e-3 {
                continue;
            }
            let f = y / ci;
            nodes.push(Node {
                omega_i: c.omega_i,
                omega_o: c.omega_o,
                ln_f: f.ln(),
            });
            samples.push(Sample {
                omega_i: c.omega_i,
                omega_o: c.omega_o,
                value: [f, f, f],
            });
        }
        self.smooth = SmoothBrdf::fit(&nodes);
        if let Ok(m) = LayeredResampler::new(&samples, &ResampleSpec::default()) {
            self.model = Some(m);
            self.model_builds += 1;
            self.model_built_with = total;
            let mut counts = HashMap::new();
            for c in &self.captures {
                *counts.entry(c.layer).or_insert(0) += 1;
            }
            self.model_layer_counts = counts;
        }
    }

    /// ln Y a model expects at a pose (the cosine included).
    pub(super) fn ln_y(&self, pose: &Pose, model: Model) -> Option<f64> {
        let inc = self.rig.forward(pose).ok()?;
        let ci = inc.omega_i.z;
        if ci <= 1e-3 || inc.omega_o.z <= 1e-3 {
            return None;
        }
        let v = match model {
            Model::Interpolant => {
                let v = self
                    .model
                    .as_ref()?
                    .at(&inc.omega_i, &inc.omega_o)
                    .ok()?
                    .value[1];
                (v > 0.0).then(|| v.ln())?
            }
            Model::Smooth => self.smooth.as_ref()?.ln_f(&inc.omega_i, &inc.omega_o)?,
        };
        let ln_y = v + ci.ln();
        ln_y.is_finite().then_some(ln_y)
    }

    /// ∂ ln Y / ∂q (per degree of the axis's reading) for joints 1 and 2 and the wagon, from
    /// `model`: a central difference, or a one-sided one where the other side leaves the data
    /// (the current θi layer is the top one in a light-outer run, and neither model
    /// extrapolates). `None` when a joint has neither side; the wagon's is NaN then.
    pub(super) fn sensitivities(&self, cmd: &[f64; 4], model: Model) -> Option<[f64; 3]> {
        let h = self.spec.sensitivity_step_deg;
        // axis 3 is the wagon (cmd[3])
        let pose = |j: usize, d: f64| {
            let mut p = Pose {
                joints_deg: [cmd[0], cmd[1], cmd[2]],
                wagon_deg: cmd[3],
            };
            if j < 3 {
                p.joints_deg[j] = cmd[j] + d;
            } else {
                p.wagon_deg = cmd[3] + d;
            }
            p
        };
        let centre = self.ln_y(&pose(0, 0.0), model)?;
        let slope = |j: usize| match (
            self.ln_y(&pose(j, h), model),
            self.ln_y(&pose(j, -h), model),
        ) {
            (Some(up), Some(down)) => Some((up - down) / (2.0 * h)),
            (Some(up), None) => Some((up - centre) / h),
            (None, Some(down)) => Some((centre - down) / h),
            (None, None) => None,
        };
        // the wagon's only where it is used (the slip's size)
        let wagon = match model {
            Model::Smooth => slope(3).unwrap_or(f64::NAN),
            Model::Interpolant => f64::NAN,
        };
        Some([slope(0)?, slope(1)?, wagon])
    }

    /// The level the sweep's θi layer predicts at its light's azimuth: the earlier lights of the
    /// layer's fitted effects L (the same back-fit, so the same gauge as the level) against
    /// their azimuths, by least squares on a constant and the harmonics a sample's outline
    /// repeats with: the 4th (a square sample's footprint returns every quarter turn), then
    /// the 2nd as well (a rectangle's, every half turn), each once `PATTERN_MIN_LIGHTS` earlier
    /// lights of the layer are in and the layer samples its period at least
    /// `PATTERN_SAMPLES_PER_PERIOD` times. (The 1st harmonic is an off-centre mount's, modelled
    /// by the drift stage.) At grazing light the pattern is as large as the steps the test looks
    /// for (±2 % at θi = 75° on the realistic preset), and consecutive sweeps share it, so
    /// unmodelled it adds up in the CUSUM. `None` while no harmonic is fitted.
    pub(super) fn expected_level(&self, sweep: &Sweep, r: &Reference) -> Option<LayerPattern> {
        let phi = |l: usize| self.light_phi.get(l).copied().unwrap_or(f64::NAN);
        let here = phi(sweep.light);
        if !here.is_finite() {
            return None;
        }
        let (lights, step) = self.layer_lights(sweep, sweep.layer, r);
        let harmonics: Vec<f64> = [(4.0, PATTERN_MIN_LIGHTS[0]), (2.0, PATTERN_MIN_LIGHTS[1])]
            .into_iter()
            .filter(|&(h, min)| lights.len() >= min && TAU / h >= PATTERN_SAMPLES_PER_PERIOD * step)
            .map(|(h, _)| h)
            .collect();
        if harmonics.is_empty() {
            return None;
        }
        let values: Vec<f64> = lights.iter().map(|&l| r.light[l]).collect();
        let azimuths: Vec<f64> = lights.iter().map(|&l| phi(l)).collect();
        // while the layer is too short an arc to fit its own 2nd harmonic, it takes the 2nd
        // harmonic with the phase of the layer below, its amplitude alone fitted, if with it
        // the layer's outline pattern (the 4th harmonic) stands out (`BORROW_SIGMAS`). (A free
        // 2nd harmonic on less than half its period, or a borrowed one in a layer without an
        // outline pattern, takes up a step instead.)
        if harmonics == [4.0] {
            if let Some(u) = self.second_harmonic_below(sweep, r) {
                if let Some(f) = pattern_fit(&azimuths, &values, &harmonics, Some(u), here) {
                    if amplitude_t(&f.coef, &f.cov, 1) >= BORROW_SIGMAS {
                        return Some(f.pattern);
                    }
                }
            }
        }
        pattern_fit(&azimuths, &values, &harmonics, None, here).map(|f| f.pattern)
    }

    /// The phase of the 2nd harmonic of the θi layer right below the sweep's, as the unit
    /// vector of its (cos 2φ, sin 2φ) coefficients: that layer's earlier lights' effects L
    /// fitted on a constant, the 4th harmonic where it samples it, and the 2nd. A sample's
    /// outline keeps its orientation from layer to layer, so its 2nd harmonic keeps its phase
    /// while its amplitude grows towards grazing. `None` unless the layer below has
    /// `PATTERN_MIN_LIGHTS[1]` lights, samples the 2nd harmonic's period
    /// `PATTERN_SAMPLES_PER_PERIOD` times, and its 2nd harmonic is `BORROW_SIGMAS` standard
    /// errors from zero.
    pub(super) fn second_harmonic_below(&self, sweep: &Sweep, r: &Reference) -> Option<[f64; 2]> {
        let below = sweep
            .past
            .iter()
            .map(|&k| self.captures[k].layer)
            .filter(|&l| l < sweep.layer)
            .max()?;
        let (lights, step) = self.layer_lights(sweep, below, r);
        if lights.len() < PATTERN_MIN_LIGHTS[1] || TAU / 2.0 < PATTERN_SAMPLES_PER_PERIOD * step {
            return None;
        }
        let harmonics: &[f64] = if TAU / 4.0 >= PATTERN_SAMPLES_PER_PERIOD * step {
            &[2.0, 4.0]
        } else {
            &[2.0]
        };
        if lights.len() <= 1 + 2 * harmonics.len() {
            return None;
        }
        let phi = |l: usize| self.light_phi.get(l).copied().unwrap_or(f64::NAN);
        let azimuths: Vec<f64> = lights.iter().map(|&l| phi(l)).collect();
        let values: Vec<f64> = lights.iter().map(|&l| r.light[l]).collect();
        let f = pattern_fit(&azimuths, &values, harmonics, None, 0.0)?;
        let amplitude = f.coef[1].hypot(f.coef[2]);
        (amplitude_t(&f.coef, &f.cov, 1) >= BORROW_SIGMAS)
            .then(|| [f.coef[1] / amplitude, f.coef[2] / amplitude])
    }

    /// The earlier lights of θi layer `layer` with a finite azimuth and a finite effect L
    /// (sorted), and the layer's azimuth step: the smallest gap between their azimuths.
    pub(super) fn layer_lights(
        &self,
        sweep: &Sweep,
        layer: i64,
        r: &Reference,
    ) -> (Vec<usize>, f64) {
        let phi = |l: usize| self.light_phi.get(l).copied().unwrap_or(f64::NAN);
        let mut lights: Vec<usize> = sweep
            .past
            .iter()
            .filter(|&&k| self.captures[k].layer == layer)
            .map(|&k| self.captures[k].light)
            .collect();
        lights.sort_unstable();
        lights.dedup();
        lights.retain(|&l| phi(l).is_finite() && r.light.get(l).is_some_and(|v| v.is_finite()));
        let mut az: Vec<f64> = lights.iter().map(|&l| phi(l).rem_euclid(TAU)).collect();
        az.sort_by(f64::total_cmp);
        let step = az
            .windows(2)
            .map(|w| w[1] - w[0])
            .filter(|g| *g > 1e-6)
            .fold(f64::INFINITY, f64::min);
        (lights, step)
    }

    /// ln Y of capture `k`, less what the drift model already explains.
    pub(super) fn ln_y_of(&self, k: usize, known: &Known) -> f64 {
        let c = &self.captures[k];
        c.y.ln()
            - known.mount.map_or(0.0, |m| m.ln_effect(&c.mount))
            - known.gain.map_or(0.0, |g| g.ln_at(c.t))
    }

    /// The F + L + C reference over the earlier sweeps, by back-fitting group means.
    pub(super) fn backfit(&self, past: &[usize], known: &Known) -> Reference {
        let n_class = self.class_ids.len();
        let n_dir = self.completed.len();
        let y: Vec<f64> = past.iter().map(|&k| self.ln_y_of(k, known)).collect();
        let cls: Vec<usize> = past.iter().map(|&k| self.class_of[k]).collect();
        let lig: Vec<usize> = past.iter().map(|&k| self.captures[k].light).collect();
        let cam: Vec<usize> = past
            .iter()
            .map(|&k| self.captures[k].camera.min(n_dir - 1))
            .collect();
        let mut f = vec![0.0; n_class];
        let mut l = vec![0.0; n_dir];
        let mut c = vec![0.0; n_dir];
        let mut work = vec![0.0; y.len()];
        for _ in 0..BACKFIT_ITERATIONS {
            for i in 0..y.len() {
                work[i] = y[i] - l[lig[i]] - c[cam[i]];
            }
            f = group_means(&work, &cls, n_class);
            for i in 0..y.len() {
                work[i] = y[i] - f[cls[i]] - c[cam[i]];
            }
            l = group_means(&work, &lig, n_dir);
            for i in 0..y.len() {
                work[i] = y[i] - f[cls[i]] - l[lig[i]];
            }
            c = group_means(&work, &cam, n_dir);
        }
        let mut seen = vec![false; n_class];
        for &k in &cls {
            seen[k] = true;
        }
        Reference {
            class: f,
            light: l,
            camera: c,
            seen,
        }
    }

    /// The current sweep's residuals against the reference (captures whose class has an
    /// earlier member), and the rows of those with sensitivities from `model`.
    pub(super) fn residuals(
        &self,
        current: &[usize],
        r: &Reference,
        known: &Known,
        model: Model,
    ) -> (Vec<f64>, Vec<Row>) {
        let n_dir = self.completed.len();
        let mut rows: Vec<Row> = Vec::new();
        let mut all: Vec<f64> = Vec::new();
        for &k in current {
            let cap = &self.captures[k];
            if !r.seen[self.class_of[k]] {
                continue;
            }
            let e = self.ln_y_of(k, known)
                - r.class[self.class_of[k]]
                - r.camera[cap.camera.min(n_dir - 1)];
            all.push(e);
            if let Some(s) = self.sensitivities(&cap.cmd, model) {
                rows.push(Row {
                    e,
                    s,
                    wagon_dir: cap.wagon_dir,
                });
            }
        }
        (all, rows)
    }

    /// The pattern: e = λ + Σ b_j s_j by SVD least squares over the rows. Rows whose
    /// sensitivity is far out of line with the sweep's others are left out first: they sit
    /// where the interpolant is least sure (a lobe's peak, a layer's edge) and, as
    /// high-leverage points, would pull the slope towards their own error. Then the fit is
    /// trimmed twice of rows beyond 3 robust residual scales (a capture the interpolant gets
    /// wrong, a bad frame) and refitted.
    pub(super) fn pattern_fit<const N: usize>(&self, mut rows: Vec<(f64, [f64; N])>) -> PatternFit {
        let caps: Vec<f64> = (0..N)
            .map(|j| {
                let v: Vec<f64> = rows.iter().map(|r| r.1[j]).collect();
                let cap = LEVERAGE_CAP * robust_scale_about_zero(&v);
                // most sensitivities exactly 0 (or none): no cap rather than a cap at 0
                if cap > 0.0 {
                    cap
                } else {
                    f64::INFINITY
                }
            })
            .collect();
        rows.retain(|r| r.1.iter().zip(&caps).all(|(v, cap)| v.abs() <= *cap));
        let p = N + 1;
        let mut fit = PatternFit {
            beta: DVector::zeros(p),
            sigma2: f64::NAN,
            inv: None,
        };
        for pass in 0..=TRIM_PASSES {
            let n = rows.len();
            if n < self.spec.min_captures {
                // too few rows left after a trim: the previous pass's fit stands
                if pass == 0 {
                    fit.inv = None;
                }
                break;
            }
            let x = DMatrix::from_fn(n, p, |i, j| if j == 0 { 1.0 } else { rows[i].1[j - 1] });
            let yv = DVector::from_iterator(n, rows.iter().map(|r| r.0));
            let svd = x.clone().svd(true, true);
            let Ok(b) = svd.solve(&yv, 1e-12) else {
                if pass == 0 {
                    fit.inv = None;
                }
                break;
            };
            let resid = &yv - &x * &b;
            fit.sigma2 = resid.norm_squared() / n.saturating_sub(p).max(1) as f64;
            let cond = svd.singular_values.max() / svd.singular_values.min().max(1e-300);
            fit.inv = if cond < 1e8 {
                (x.transpose() * &x).try_inverse()
            } else {
                None
            };
            fit.beta = b;
            let cut = TRIM_SCALES * robust_scale_about_zero(resid.as_slice());
            if !(cut > 0.0) || resid.iter().all(|r| r.abs() <= cut) {
                break;
            }
            let mut keep = resid.iter().map(|r| r.abs() <= cut);
            rows.retain(|_| keep.next().unwrap_or(false));
        }
        fit
    }
}
