use super::*;
use crate::measure::geometry::Spherical;
use crate::measure::kinematics::Incidence;
use crate::measure::plan::{PlanDirection, SamplingPlan};

/// A smooth isotropic BRDF: Lambert plus a Phong lobe about the mirror direction.
pub(super) fn brdf(wi: &Vec3, wo: &Vec3) -> f64 {
    let m = Vec3::new(-wi.x, -wi.y, wi.z);
    0.3 + 2.0 * m.dot(wo).max(0.0).powi(4)
}

/// The nominal directions and the rig's pose of a plan entry (none where it cannot reach).
pub(super) fn plan_pose(
    rig: &Rig,
    l: &PlanDirection,
    c: &PlanDirection,
) -> Option<(Incidence, Pose)> {
    let inc = Incidence {
        omega_i: Spherical::from_deg(l.theta_deg, l.phi_deg).to_vector(),
        omega_o: c.spherical().to_vector(),
    };
    let pose = rig.inverse(&inc).ok()?;
    Some((inc, pose))
}

fn session() -> (SweepMonitor, Vec<SweepCapture>, Rig) {
    let plan = SamplingPlan::ubo();
    let rig = Rig::new(Default::default()).unwrap();
    let mut m = SweepMonitor::new(SweepSpec::default(), rig.clone(), plan.direction_count());
    let dirs = plan.directions().to_vec();
    let mut caps = Vec::new();
    for e in 0..plan.capture_count() {
        let pe = plan.entry(e).unwrap();
        let (l, c) = (dirs[pe.light], dirs[pe.camera]);
        let Some((inc, pose)) = plan_pose(&rig, &l, &c) else {
            continue;
        };
        let y = brdf(&inc.omega_i, &inc.omega_o) * inc.omega_i.z;
        let cap = SweepCapture {
            idx: e as u64,
            t: 7.0 * e as f64,
            entry: e,
            light: pe.light,
            camera: pe.camera,
            class: (0, 0, e as i64),
            layer: (l.theta_deg * 1000.0).round() as i64,
            omega_i: inc.omega_i,
            omega_o: inc.omega_o,
            cmd: [
                pose.joints_deg[0],
                pose.joints_deg[1],
                pose.joints_deg[2],
                pose.wagon_deg,
            ],
            wagon_dir: 0.0,
            y,
            mount: [0.0; 4],
        };
        m.add(cap.clone());
        caps.push(cap);
    }
    (m, caps, rig)
}

#[test]
fn sensitivities_follow_the_true_brdf() {
    let (mut m, caps, rig) = session();
    // every capture is its own class here: its effect is its own ln Y
    let effects: Vec<f64> = caps.iter().map(|c| c.y.ln()).collect();
    m.ensure_model(60_000, &effects);
    let truth = |cmd: &[f64; 4], j: usize| {
        let f = |d: f64| {
            let mut p = Pose {
                joints_deg: [cmd[0], cmd[1], cmd[2]],
                wagon_deg: cmd[3],
            };
            p.joints_deg[j] += d;
            let inc = rig.forward(&p).unwrap();
            (brdf(&inc.omega_i, &inc.omega_o) * inc.omega_i.z).ln()
        };
        (f(1.0) - f(-1.0)) / 2.0
    };
    let (mut num, mut den_m, mut den_t, mut n) = (0.0, 0.0, 0.0, 0);
    for cap in caps.iter().step_by(7) {
        if cap.omega_i.z < 0.3 || cap.omega_o.z < 0.3 {
            continue;
        }
        let Some(s) = m.sensitivities(&cap.cmd, Model::Interpolant) else {
            continue;
        };
        for j in 0..2 {
            let t = truth(&cap.cmd, j);
            num += s[j] * t;
            den_m += s[j] * s[j];
            den_t += t * t;
        }
        n += 1;
    }
    let corr = num / (den_m * den_t).sqrt();
    eprintln!(
        "n {n} corr {corr:.3} rms model {:.4} rms truth {:.4}",
        (den_m / n as f64).sqrt(),
        (den_t / n as f64).sqrt()
    );
    assert!(corr > 0.9, "{corr}");
}
