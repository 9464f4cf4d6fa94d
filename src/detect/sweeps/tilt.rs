//! The light-side tilt: a stationary pattern of the light's direction that is linear in its
//! gnomonic coordinates tan θi·(cos φi, sin φi).
//!
//! A sample seated tilted by τ towards azimuth φ₀ (a burr under its holder's edge, a wedge, a
//! holder not square to the arm's last joint) is lit at cos(θi − τ cos(φi − φ₀)) where the
//! daemon divides by cos θi: ln Y moves by τ·tan θi·cos(φi − φ₀), from the first capture on. A
//! lamp beam that falls off across the arm's reach makes the same pattern. It is the first
//! harmonic of the light's azimuth, which the level test's layer patterns leave out (over part
//! of a turn it takes up a step), so unmodelled it reads as level changes where the light turns
//! towards and away from the tilt, growing towards grazing: on the synthetic sessions a 0.5°
//! tilt raised one to three false gain steps a run.
//!
//! It is identified across the completed θi layers below the current one with at least
//! `MIN_LAYER_LIGHTS` lights, each on its own: the layer's light effects L (the back-fit's, the
//! pattern put back) on a constant, a ramp in time (a drift the gain path misses is no
//! harmonic), the even harmonics the layer samples (`PATTERN_SAMPLES_PER_PERIOD`), a column per
//! gain step raised in it (half a turn of a level shift is a first harmonic) and the first
//! harmonic, divided by the layer's tan θi. A tilt gives every layer the same coefficients; a
//! step or a slip inside one layer gives that layer a first harmonic of its own, which the
//! others do not share. So the layers' coefficients are pooled (inverse covariance weights)
//! only when they agree (`HOMOGENEITY_CHI2`: Cochran's Q against χ² at 99.9 %), from two layers
//! on, and the pattern is modelled when the pooled amplitude stands `TILT_SIGMAS` standard
//! errors from zero. Each layer's noise is its residual variance, floored at its sweeps' mean
//! squared level standard error (a layer of few lights can fit its own noise away).
//!
//! It is estimated again at each new layer, and the model is the latest estimate: a pattern the
//! layers stop agreeing on is dropped. A named joint slip changed the pose (a joint-1 slip tilts
//! the sample itself): only layers wholly after it are used from then on. The current layer
//! takes the tilt extrapolated by the tan θi law, and once it has lights enough for its own 2nd
//! harmonic it keeps it only if its lights fit its pattern better with it than without it
//! (`SweepMonitor::expected_level`): a light-side pattern that stops growing as tan θi at
//! grazing light would otherwise make level changes of its own.
//!
//! Taking it out of ln Y moves only the light effects L: the class and camera effects and every
//! sweep's pattern across its cameras (the joint and wagon tests) are unchanged, and the level
//! test judges each sweep against its layer less the tilt. The drift model takes it out of the
//! isotropy classes' pairs too (`DriftDetector::set_light_tilt`): in light-outer order the
//! pattern moves with time as a rate does.

use super::model::PATTERN_SAMPLES_PER_PERIOD;
use super::*;

/// The pooled amplitude needed, in standard errors along its own direction.
pub(crate) const TILT_SIGMAS: f64 = 3.0;
/// The 99.9 % quantiles of χ² for 2, 4, 6, 8 and 10 degrees of freedom: the layers'
/// coefficients agree when Cochran's Q (2 degrees of freedom a layer beyond the first) is
/// below.
pub(super) const HOMOGENEITY_CHI2: [f64; 5] = [13.816, 18.467, 22.458, 26.124, 29.588];
/// Layers with fewer lights are not used: the UBO plan's θi = 15° layer has 6, too few
/// degrees of freedom for the agreement test to have power.
const MIN_LAYER_LIGHTS: usize = 12;

/// The light-side tilt as estimated: ln Y per unit of tan θi·cos φi and tan θi·sin φi, the
/// pooled standard error along its direction, the layers it was pooled from (θi in degrees),
/// Cochran's Q of their agreement and its threshold.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct LightTilt {
    pub coef: [f64; 2],
    pub se: f64,
    pub layers_deg: Vec<f64>,
    pub q: f64,
    pub q_threshold: f64,
}

impl LightTilt {
    /// Its amplitude (ln units per unit tan θi) and the azimuth it points to (degrees, sample
    /// frame): the tilt in radians and its direction, for a tilted sample.
    pub(crate) fn polar(&self) -> (f64, f64) {
        (
            self.coef[0].hypot(self.coef[1]),
            self.coef[1]
                .atan2(self.coef[0])
                .to_degrees()
                .rem_euclid(360.0),
        )
    }
}

/// Whether the tilt has been named: once a run, at the first sweep that reaches the tests
/// after it is first modelled (a layer's first sweep may not).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
enum Naming {
    #[default]
    NotYet,
    Due,
    Done,
}

/// The tilt the sweeps model: the latest estimate, the θi layer it was made at, and the named
/// slip (its first capture) the layers it used lie after.
#[derive(Debug, Clone, Default)]
pub(super) struct TiltState {
    model: Option<LightTilt>,
    layer: Option<i64>,
    slip: Option<u64>,
    naming: Naming,
}

impl TiltState {
    /// The modelled tilt.
    pub(super) fn model(&self) -> Option<&LightTilt> {
        self.model.as_ref()
    }

    /// The modelled tilt's coefficients.
    pub(super) fn coef(&self) -> Option<[f64; 2]> {
        self.model.as_ref().map(|t| t.coef)
    }

    /// The finding that names the tilt, once, at sweep `at`.
    pub(super) fn name_at(&mut self, at: SweepAt) -> Option<SweepFinding> {
        if self.naming != Naming::Due {
            return None;
        }
        self.naming = Naming::Done;
        self.model
            .clone()
            .map(|tilt| SweepFinding::LightTilt { at, tilt })
    }
}

/// One layer's own first harmonic per unit tan θi and its covariance.
struct LayerHarmonic {
    theta_deg: f64,
    v: [f64; 2],
    cov: [[f64; 2]; 2],
}

/// Inverse of a symmetric 2 × 2 matrix; `None` when singular or not finite.
fn inverse2(m: [[f64; 2]; 2]) -> Option<[[f64; 2]; 2]> {
    let det = m[0][0] * m[1][1] - m[0][1] * m[1][0];
    (det.is_finite() && det > 0.0).then(|| {
        [
            [m[1][1] / det, -m[0][1] / det],
            [-m[1][0] / det, m[0][0] / det],
        ]
    })
}

/// Pools the layers' harmonics when they agree: `None` with fewer than two layers, when
/// Cochran's Q exceeds `HOMOGENEITY_CHI2`, or when the pooled amplitude is under `TILT_SIGMAS`
/// standard errors.
fn pool(layers: &[LayerHarmonic]) -> Option<LightTilt> {
    if layers.len() < 2 {
        return None;
    }
    let mut w = [[0.0; 2]; 2];
    let mut wv = [0.0; 2];
    let mut inv = Vec::with_capacity(layers.len());
    for l in layers {
        let p = inverse2(l.cov)?;
        for i in 0..2 {
            for j in 0..2 {
                w[i][j] += p[i][j];
            }
            wv[i] += p[i][0] * l.v[0] + p[i][1] * l.v[1];
        }
        inv.push(p);
    }
    let cov = inverse2(w)?;
    let v = [
        cov[0][0] * wv[0] + cov[0][1] * wv[1],
        cov[1][0] * wv[0] + cov[1][1] * wv[1],
    ];
    let q: f64 = layers
        .iter()
        .zip(&inv)
        .map(|(l, p)| {
            let d = [l.v[0] - v[0], l.v[1] - v[1]];
            d[0] * (p[0][0] * d[0] + p[0][1] * d[1]) + d[1] * (p[1][0] * d[0] + p[1][1] * d[1])
        })
        .sum();
    let q_threshold = *HOMOGENEITY_CHI2.get(layers.len() - 2)?;
    let amplitude = v[0].hypot(v[1]);
    if !(q.is_finite() && q <= q_threshold && amplitude > 0.0) {
        return None;
    }
    let u = [v[0] / amplitude, v[1] / amplitude];
    let var =
        u[0] * (cov[0][0] * u[0] + cov[0][1] * u[1]) + u[1] * (cov[1][0] * u[0] + cov[1][1] * u[1]);
    let se = var.sqrt();
    (se.is_finite() && se > 0.0 && amplitude >= TILT_SIGMAS * se).then(|| LightTilt {
        coef: v,
        se,
        layers_deg: layers.iter().map(|l| l.theta_deg).collect(),
        q,
        q_threshold,
    })
}

impl SweepMonitor {
    /// At a new θi layer, the tilt estimated again from the layers below (`known` and the
    /// `reference` built with it are updated when the model changes). A joint slip named since
    /// the last estimate drops it first: the pose changed.
    pub(super) fn update_tilt(
        &mut self,
        sweep: &Sweep,
        known: &mut Known,
        reference: &mut Reference,
    ) {
        if self.tilt.layer == Some(sweep.layer) {
            return;
        }
        self.tilt.layer = Some(sweep.layer);
        let slip = self.slip.map(|s| s.2);
        if self.tilt.slip != slip {
            self.tilt.slip = slip;
            if self.tilt.model.take().is_some() {
                known.tilt = None;
                *reference = self.backfit(&sweep.past, known);
            }
        }
        let estimate = self.estimate_tilt(sweep, reference, known.tilt);
        let coef = estimate.as_ref().map(|t| t.coef);
        if coef != known.tilt {
            known.tilt = coef;
            *reference = self.backfit(&sweep.past, known);
        }
        if estimate.is_some() && self.tilt.naming == Naming::NotYet {
            self.tilt.naming = Naming::Due;
        }
        self.tilt.model = estimate;
    }

    /// The light-side tilt from the completed θi layers below the sweep's (the module comment),
    /// from the reference `r` built with `current` taken out of ln Y.
    pub(super) fn estimate_tilt(
        &self,
        sweep: &Sweep,
        r: &Reference,
        current: Option<[f64; 2]>,
    ) -> Option<LightTilt> {
        // a named slip changed the pose (a joint-1 slip tilts the sample itself): only the
        // layers wholly after it
        let after = self.slip.map_or(0, |(_, _, idx)| idx);
        let mut layers: Vec<i64> = sweep
            .past
            .iter()
            .map(|&k| self.captures[k].layer)
            .filter(|&l| l < sweep.layer && l > 0)
            .collect();
        layers.sort_unstable();
        layers.dedup();
        layers.retain(|&l| {
            self.sweep_starts
                .iter()
                .filter(|s| s.layer == l)
                .all(|s| s.first_idx >= after)
        });
        let fits: Vec<LayerHarmonic> = layers
            .into_iter()
            .filter_map(|layer| self.layer_harmonic(sweep, layer, r, current))
            .collect();
        pool(&fits)
    }

    /// One layer's first harmonic per unit tan θi (`None` when the layer has fewer than
    /// `MIN_LAYER_LIGHTS` lights or leaves no degree of freedom). In light-outer order a layer
    /// below the sweep's is complete.
    fn layer_harmonic(
        &self,
        sweep: &Sweep,
        layer: i64,
        r: &Reference,
        current: Option<[f64; 2]>,
    ) -> Option<LayerHarmonic> {
        let theta = (layer as f64 / 1000.0).to_radians();
        let tan = theta.tan();
        if !(tan.is_finite() && tan > 0.0) {
            return None;
        }
        let (lights, step) = self.layer_lights(sweep, layer, r);
        if lights.len() < MIN_LAYER_LIGHTS || !step.is_finite() {
            return None;
        }
        let phi = |l: usize| self.light_phi.get(l).copied().unwrap_or(f64::NAN);
        let mut harmonics = vec![1.0];
        for h in [2.0, 4.0] {
            if TAU / h >= PATTERN_SAMPLES_PER_PERIOD * step {
                harmonics.push(h);
            }
        }
        // a gain step raised in the layer: the lights from its start on are shifted by it until
        // the drift model's gain path carries it, and half a turn of shift is a first harmonic
        let start_t = |l: usize| {
            self.sweep_starts
                .iter()
                .rev()
                .find(|s| s.light == l)
                .map_or(f64::NAN, |s| s.first_t)
        };
        let steps: Vec<f64> = self
            .level_steps
            .iter()
            .filter(|s| s.0 == layer)
            .filter_map(|s| s.2)
            .collect();
        let cols = 2 + 2 * harmonics.len() + steps.len();
        let n = lights.len();
        if n <= cols {
            return None;
        }
        let t0 = lights.iter().map(|&l| start_t(l)).sum::<f64>() / n as f64;
        let x = DMatrix::from_fn(n, cols, |i, j| {
            let p = phi(lights[i]);
            let k = 2 * harmonics.len();
            if j == 0 {
                1.0
            } else if j > k + steps.len() {
                (start_t(lights[i]) - t0) / 3600.0
            } else if j > k {
                f64::from(u8::from(start_t(lights[i]) >= steps[j - k - 1]))
            } else {
                let h = harmonics[(j - 1) / 2];
                if j % 2 == 1 {
                    (h * p).cos()
                } else {
                    (h * p).sin()
                }
            }
        });
        let y = DVector::from_iterator(
            n,
            lights
                .iter()
                .map(|&l| r.light[l] + current.map_or(0.0, |c| self.tilt_effect(c, l, layer))),
        );
        let xtx_inv = (x.transpose() * &x).try_inverse()?;
        let b = &xtx_inv * x.transpose() * &y;
        let resid = &y - &x * &b;
        let mut sigma2 = resid.norm_squared() / (n - cols) as f64;
        // floored at the layer's sweeps' own level variance
        let spans: Vec<f64> = self
            .sweep_starts
            .iter()
            .filter(|s| s.layer == layer && s.level_se.is_finite())
            .map(|s| s.level_se * s.level_se)
            .collect();
        if !spans.is_empty() {
            sigma2 = sigma2.max(spans.iter().sum::<f64>() / spans.len() as f64);
        }
        let scale = sigma2 / (tan * tan);
        let v = [b[1] / tan, b[2] / tan];
        let cov = [
            [xtx_inv[(1, 1)] * scale, xtx_inv[(1, 2)] * scale],
            [xtx_inv[(2, 1)] * scale, xtx_inv[(2, 2)] * scale],
        ];
        (v.iter().all(|c| c.is_finite()) && sigma2.is_finite()).then_some(LayerHarmonic {
            theta_deg: layer as f64 / 1000.0,
            v,
            cov,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn layer(theta_deg: f64, v: [f64; 2], se: f64) -> LayerHarmonic {
        LayerHarmonic {
            theta_deg,
            v,
            cov: [[se * se, 0.0], [0.0, se * se]],
        }
    }

    #[test]
    fn layers_that_agree_pool_and_a_layer_of_its_own_does_not() {
        // a 0.5° tilt towards 60°: 0.87 % per unit tan θi in every layer
        let t = 0.5f64.to_radians();
        let v = [t * 60f64.to_radians().cos(), t * 60f64.to_radians().sin()];
        let agree = [
            layer(30.0, v, 0.001),
            layer(45.0, [v[0] + 0.001, v[1]], 0.0008),
        ];
        let p = pool(&agree).expect("pooled");
        let (amp, az) = p.polar();
        assert!((amp - t).abs() < 0.001 && (az - 60.0).abs() < 8.0, "{p:?}");
        assert_eq!(p.layers_deg, vec![30.0, 45.0]);
        assert!(p.q < p.q_threshold && p.q_threshold == HOMOGENEITY_CHI2[0]);
        // one layer alone is never pooled
        assert!(pool(&agree[..1]).is_none());
        // a step inside the 45° layer: a first harmonic there, none below
        let step = [
            layer(15.0, [0.0, 0.0], 0.002),
            layer(30.0, [0.0, 0.0], 0.001),
            layer(45.0, [0.009, 0.0], 0.0008),
        ];
        assert!(pool(&step).is_none());
        // agreeing layers with nothing in them: no pattern
        let flat = [
            layer(30.0, [0.0005, 0.0], 0.001),
            layer(45.0, [-0.0004, 0.0002], 0.0008),
        ];
        assert!(pool(&flat).is_none());
        // singular or non-finite covariances are refused, not pooled
        let bad = [layer(30.0, v, 0.0), layer(45.0, v, f64::NAN)];
        assert!(pool(&bad).is_none());
    }
}
