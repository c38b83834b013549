//! Issue #15, measurements 6-8 of `docs/dukf-reproduction.md`: the reference scenario with the follower's controller in a
//! *closed loop* on the formation filter, as on a robot: the separation-bearing controller
//! gets the filter's estimates of `(l12, alpha12, beta12)` for feedback and of `(v1, w1)` for
//! feed-forward, instead of the truth and the true leader inputs. The follower's inputs then
//! carry no information the filter does not already have.
//!
//! ```text
//! cargo run -p formation-sim --example dukf_closed_loop [-- FIRST LAST]   (seeds, default 1 20)
//! ```
//! Prints, per filter in the loop, the medians over the seeds of the MSEs of the loop
//! filter's estimates and of the two single-measurement baselines run over the same
//! (closed-loop) measurements, and the RMS velocity errors after 2 s. The baselines cannot
//! be put in the loop themselves (they estimate no leader velocity), so they are scored on the
//! trajectory the dual UKF drove. With `CA=J1,J2,...` it also runs, on the closed-loop, the
//! open-loop reference and both fixtures, a joint UKF with a constant-acceleration leader
//! model for each jerk `J` (measurement 8) and the oracle told the true leader inputs
//! (measurement 6; its velocity columns are meaningless, it estimates no velocity).
#![allow(clippy::unwrap_used)]

use formation_filter::FilterDesign;
use formation_filter::FormationFilter;
use formation_sim::reproduce::{Baseline, baseline, paper_filter_config_with, run_filter};
use formation_sim::scenario::reference_leader_inputs;
use formation_sim::scenario::{PAPER_X0, Sample, Scenario, ScenarioConfig};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use unicycle::{ControllerConfig, Formation, PolarModel, SeparationBearingController, wrap_angle};

#[path = "common/median.rs"]
mod median;
use median::median;

/// Simulates the reference scenario with the dual UKF in the follower's control loop.
fn closed_loop(seed: u64) -> Scenario {
    let config = ScenarioConfig::reference(seed);
    let model = PolarModel::new(config.d).unwrap();
    let start = Formation::from_poses(&config.leader0, &config.follower0, config.d).unwrap();
    let controller =
        SeparationBearingController::new(config.d, ControllerConfig::hold(&start)).unwrap();
    let mut filter = FormationFilter::new(&paper_filter_config_with(
        config.d,
        config.dt,
        FilterDesign::Dual,
    ))
    .unwrap();
    let noise: Vec<Normal<f64>> = config
        .noise_std
        .iter()
        .map(|&s| Normal::new(0.0, s).unwrap())
        .collect();
    let mut rng = ChaCha8Rng::seed_from_u64(config.seed);
    let r = config.noise_covariance();
    let (mut leader, mut follower) = (config.leader0, config.follower0);
    let mut samples: Vec<Sample> = Vec::new();
    for k in 0..=config.steps() {
        let t = k as f64 * config.dt;
        let truth = model.state_from_poses(&leader, &follower).unwrap();
        let mut y = PolarModel::h(&truth);
        for i in 0..3 {
            y[i] += noise[i].sample(&mut rng);
        }
        let y = formation_filter::MEASUREMENT_SPACE.normalize(&y);
        if let Some(prev) = samples.last() {
            filter.step(&y, &r, prev.follower_inputs).unwrap();
        }
        let u1 = reference_leader_inputs(t);
        // The controller sees only the filter's estimates.
        let u2 = controller
            .inputs(&filter.formation(), filter.leader_velocity())
            .unwrap();
        samples.push(Sample {
            t,
            truth,
            follower,
            leader_inputs: u1,
            follower_inputs: u2,
            // Exact actuation and odometry: the paper's setting.
            executed_inputs: u2,
            odometry: u2,
            measurement: y,
            controller: ControllerConfig::hold(&start),
        });
        leader = leader.integrate_exact(u1, config.dt).unwrap();
        follower = follower.integrate_exact(u2, config.dt).unwrap();
    }
    Scenario { config, samples }
}

fn main() {
    let args: Vec<u64> = std::env::args()
        .skip(1)
        .map(|a| a.parse().unwrap())
        .collect();
    let (lo, hi) = (
        args.first().copied().unwrap_or(1),
        args.get(1).copied().unwrap_or(20),
    );
    let x0 = [PAPER_X0[3], PAPER_X0[4], PAPER_X0[5]];
    let (mut dual, mut smooth, mut rw, mut cv) = (vec![], vec![], vec![], vec![]);
    let mut spread = vec![];
    for seed in lo..=hi {
        let s = closed_loop(seed);
        let run = run_filter(
            &s,
            &paper_filter_config_with(s.config.d, s.config.dt, FilterDesign::Dual),
        )
        .unwrap();
        dual.push(run.summary);
        smooth.push(run.smoothed_summary);
        rw.push(baseline(&s, &x0, Baseline::RANDOM_WALK));
        cv.push(baseline(&s, &x0, Baseline::CONSTANT_VELOCITY));
        // How far the true formation strays from its set-point.
        let l: Vec<f64> = s.samples.iter().map(|x| x.truth[3]).collect();
        let a: Vec<f64> = s.samples.iter().map(|x| x.truth[4]).collect();
        let range = |v: &[f64]| {
            v.iter().fold(f64::NEG_INFINITY, |m, x| m.max(*x))
                - v.iter().fold(f64::INFINITY, |m, x| m.min(*x))
        };
        spread.push((range(&l), range(&a)));
    }
    let m = |v: &[formation_sim::reproduce::Summary],
             f: fn(&formation_sim::reproduce::Summary) -> f64| {
        median(v.iter().map(f).collect())
    };
    let m3 = |v: &[[f64; 3]], i: usize| median(v.iter().map(|x| x[i]).collect());
    println!("closed loop, seeds {lo}..{hi}, medians");
    println!(
        "true formation range: l12 {:.4} m, alpha12 {:.4} rad",
        median(spread.iter().map(|x| x.0).collect()),
        median(spread.iter().map(|x| x.1).collect())
    );
    println!(
        "{:<22} {:>10} {:>10} {:>10} {:>8} {:>8}",
        "filter", "l12", "alpha12", "beta12", "rms v1", "rms w1"
    );
    for (name, v) in [
        ("dual UKF (in the loop)", &dual),
        ("smoothed (offline)", &smooth),
    ] {
        println!(
            "{name:<22} {:>10.3e} {:>10.3e} {:>10.3e} {:>8.4} {:>8.4}",
            m(v, |s| s.mse.l12),
            m(v, |s| s.mse.alpha12),
            m(v, |s| s.mse.beta12),
            m(v, |s| s.rms_v1_after_2s),
            m(v, |s| s.rms_w1_after_2s)
        );
    }
    for (name, v) in [("RW baseline", &rw), ("CV baseline", &cv)] {
        println!(
            "{name:<22} {:>10.3e} {:>10.3e} {:>10.3e}",
            m3(v, 0),
            m3(v, 1),
            m3(v, 2)
        );
    }
    if std::env::var("CA").is_err() {
        return;
    }
    // Measurement 7: a constant-acceleration leader model, jerk from the tuning rule.
    let closed = ((lo..=hi).map(closed_loop).collect::<Vec<_>>(), PAPER_X0);
    let open = (
        (lo..=hi)
            .map(|s| formation_sim::scenario::simulate(&ScenarioConfig::reference(s)).unwrap())
            .collect::<Vec<_>>(),
        PAPER_X0,
    );
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/scenarios");
    let fixture = |name: &str| -> (Vec<Scenario>, [f64; 6]) {
        let spec = formation_sim::scenario_file::ScenarioSpec::load(&root.join(name)).unwrap();
        let x0 = spec.filter_x0();
        (
            (lo..=hi)
                .map(|s| spec.simulate(s, false).unwrap())
                .collect(),
            x0,
        )
    };
    let (step, turn) = (fixture("l12-step.yaml"), fixture("hard-turn.yaml"));
    let jerks: Vec<f64> = std::env::var("CA")
        .unwrap()
        .split(',')
        .filter_map(|x| x.parse().ok())
        .collect();
    for (jerk, told) in jerks
        .iter()
        .map(|&j| ([j, j], false))
        .chain([([0.0, 0.0], true)])
    {
        print_ca("closed loop (dual UKF driving)", &closed, jerk, told);
        print_ca("open-loop reference", &open, jerk, told);
        print_ca("l12-step.yaml", &step, jerk, told);
        print_ca("hard-turn.yaml", &turn, jerk, told);
    }
}

/// A joint UKF over `[x (6), v1, w1, a_v, a_w]`: the leader's velocities driven by their
/// accelerations, the accelerations a random walk with per-step standard deviation
/// `jerk * dt` (the tuning rule: the leader's largest jerk, `[m/s^3, rad/s^3]`). Returns the
/// MSEs of `l12, alpha12, beta12`, the RMS `v1, w1` errors after 2 s and the mean formation
/// NEES after 2 s. With `told`, the oracle: the prediction uses the *true* leader inputs of
/// each step instead of the state's velocities, and the formation's process noise is 0 (the
/// simulation has none), so no causal filter can do better.
fn joint_ca(s: &Scenario, x0: &[f64; 6], jerk: [f64; 2], told: bool) -> [f64; 6] {
    use nalgebra::{SMatrix, SVector, Vector2, Vector3};
    let dt = s.config.dt;
    let model = PolarModel::new(s.config.d).unwrap();
    let mut z0 = SVector::<f64, 10>::zeros();
    z0.fixed_rows_mut::<6>(0).copy_from_slice(x0);
    let mut p0 = SVector::<f64, 10>::from_row_slice(&[
        0.01, 0.01, 0.01, 0.0049, 0.0009, 0.0009, 1.0, 1.0, 0.04, 0.04,
    ]);
    p0[0] = 0.01;
    let space = dukf::AngleMask::<10>::from_indices(&[2, 4, 5]).unwrap();
    let mspace = dukf::AngleMask::<3>::from_indices(&[1, 2]).unwrap();
    let mut ukf = dukf::Ukf::new(
        z0,
        SMatrix::from_diagonal(&p0),
        space,
        dukf::UtParams::new(1.0, 2.0, 0.0),
    )
    .unwrap();
    let mut qd = SVector::<f64, 10>::zeros();
    qd.fixed_rows_mut::<6>(0)
        .copy_from_slice(&[1e-6, 1e-6, 1e-6, 1e-9, 1e-9, 1e-9]);
    if told {
        qd.fixed_rows_mut::<3>(3).fill(0.0);
    }
    qd[8] = (jerk[0] * dt).powi(2);
    qd[9] = (jerk[1] * dt).powi(2);
    let q = SMatrix::<f64, 10, 10>::from_diagonal(&qd);
    let r = s.config.noise_covariance();
    let (mut e, mut late, mut n_late, mut nees) = ([0.0; 3], [0.0; 2], 0.0, 0.0);
    for pair in s.samples.windows(2) {
        let (prev, now) = (&pair[0], &pair[1]);
        let u: Vector2<f64> = prev.follower_inputs.into();
        ukf.predict(
            |z| {
                let x = unicycle::PolarState::from_row_slice(&z.as_slice()[..6]);
                let w = if told {
                    prev.leader_inputs.into()
                } else {
                    Vector2::new(z[6], z[7])
                };
                let nx = model
                    .f(&x, &u, &w, dt)
                    .unwrap_or(unicycle::PolarState::repeat(f64::NAN));
                let mut o = *z;
                o.fixed_rows_mut::<6>(0).copy_from(&nx);
                o[6] += z[8] * dt;
                o[7] += z[9] * dt;
                o
            },
            &q,
        )
        .unwrap();
        ukf.update(
            &now.measurement,
            |z| Vector3::new(z[3], z[4], z[5]),
            &r,
            &mspace,
        )
        .unwrap();
        let z = ukf.state();
        let t = PolarModel::h(&now.truth);
        let ex = Vector3::new(
            z[3] - t[0],
            wrap_angle(z[4] - t[1]),
            wrap_angle(z[5] - t[2]),
        );
        for i in 0..3 {
            e[i] += ex[i] * ex[i];
        }
        if now.t > 2.0 {
            late[0] += (z[6] - prev.leader_inputs.v).powi(2);
            late[1] += (z[7] - prev.leader_inputs.w).powi(2);
            n_late += 1.0;
            let p = ukf.covariance().fixed_view::<3, 3>(3, 3).into_owned();
            nees += ex.dot(&(p.try_inverse().unwrap() * ex));
        }
    }
    let n = (s.samples.len() - 1) as f64;
    [
        e[0] / n,
        e[1] / n,
        e[2] / n,
        (late[0] / n_late).sqrt(),
        (late[1] / n_late).sqrt(),
        nees / n_late,
    ]
}

/// The constant-acceleration joint UKF on a list of scenarios, medians printed.
fn print_ca(label: &str, (scenarios, x0): &(Vec<Scenario>, [f64; 6]), jerk: [f64; 2], told: bool) {
    let runs: Vec<[f64; 6]> = scenarios
        .iter()
        .map(|s| joint_ca(s, x0, jerk, told))
        .collect();
    let label = if told {
        format!("ORACLE {label}")
    } else {
        label.to_string()
    };
    let m = |i: usize| median(runs.iter().map(|r| r[i]).collect());
    println!(
        "{label:<40} jerk {:?}: l12 {:.3e} alpha12 {:.3e} beta12 {:.3e} | rms v1 {:.4} w1 {:.4} | NEES {:.2}",
        jerk,
        m(0),
        m(1),
        m(2),
        m(3),
        m(4),
        m(5)
    );
}
