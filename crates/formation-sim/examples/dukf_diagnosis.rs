//! The measurements behind issue #15's diagnosis (`docs/dukf-reproduction.md`, "Why the dual
//! UKF loses to the baselines"): the dual UKF under other tunings, and a joint (augmented)
//! UKF over `[x1, y1, theta1, l12, alpha12, beta12, v1, w1]`, on the reference scenario or on
//! variants of its leader, with the two single-measurement baselines beside them.
//!
//! ```text
//! cargo run -p formation-sim --example dukf_diagnosis < LINES
//! LEADER=const|slow|ref SEEDS=1..20 (defaults: ref, 1..20)
//! SCENARIO=fixtures/scenarios/NAME.yaml (a scenario file instead of LEADER)
//! ```
//! Each stdin line is one configuration:
//! - 11 numbers, the dual UKF: `Rr_v Rr_w Q_l Q_alpha Q_beta Q_pose Pw0_v Pw0_w propagate
//!   ut_alpha P0_pose_scale`; `Pw0_v < 0.5` starts `w0` at the leader velocity that holds the
//!   formation given the follower's first inputs (instead of `[0, 0]`).
//! - 5 numbers, the joint UKF: `Rr_v Rr_w Q_formation Pw0 ut_alpha`, with the same `w0` rule
//!   when `Pw0 < 0.5`.
//! - 1 number, the oracle: the joint UKF told the *true* leader inputs at every step (no
//!   filter can know more), with `Q_formation` on `l12, alpha12, beta12`. It bounds what any
//!   model-based filter can reach on the scenario.
//! - 3 numbers, the formation-holding prior: `Rr_dv Rr_dw Pdelta0`; the leader velocity is the
//!   one that holds the estimated `l12`, `alpha12` given the follower's inputs, plus a
//!   random-walk deviation (measurement 5 of the document).
//! - 4 numbers, the same for `v1` only, `w1` a free random walk: `Rr_dv Rr_w Pdelta0 0`.
//!
//! It prints the medians over the seeds of the MSEs of `l12, alpha12, beta12`, the RMS errors
//! of `v1, w1` after 2 s, and the NIS / NEES averaged over the seeds per step.
#![allow(
    clippy::unwrap_used,
    clippy::needless_range_loop,
    clippy::too_many_lines,
    clippy::type_complexity
)]
use formation_filter::FilterDesign;
use formation_sim::reproduce::{Baseline, baseline, paper_filter_config_with, run_filter};
use formation_sim::scenario::{PAPER_X0, ScenarioConfig, simulate};
use nalgebra::{Matrix2, SMatrix, SVector, Vector2};

#[path = "common/median.rs"]
mod median;
use median::median;

/// The scenarios of the seeds (env `SEEDS`, `SCENARIO`, `LEADER`) and the filters' initial state.
fn scenarios() -> (Vec<formation_sim::scenario::Scenario>, [f64; 6]) {
    let seeds: Vec<u64> = std::env::var("SEEDS")
        .map(|s| {
            let (a, b) = s.split_once("..").unwrap();
            (a.parse().unwrap()..=b.parse().unwrap()).collect()
        })
        .unwrap_or((1..=20).collect());
    let spec = std::env::var("SCENARIO").ok().map(|p| {
        formation_sim::scenario_file::ScenarioSpec::load(std::path::Path::new(&p)).unwrap()
    });
    let full_x0 = spec.as_ref().map_or(PAPER_X0, |s| s.filter_x0());
    let leader = std::env::var("LEADER").unwrap_or_default();
    let scen: Vec<_> = seeds
        .iter()
        .map(|&s| {
            if let Some(spec) = &spec {
                return spec.simulate(s, false).unwrap();
            }
            let c = ScenarioConfig::reference(s);
            match leader.as_str() {
                "const" => {
                    formation_sim::scenario::simulate_with(&c, |_| unicycle::Inputs::new(0.8, 0.1))
                        .unwrap()
                }
                "slow" => formation_sim::scenario::simulate_with(&c, |t| {
                    unicycle::Inputs::new(0.8 + 0.02 * (0.5 * t).sin(), 0.02 * (0.4 * t).sin())
                })
                .unwrap(),
                _ => simulate(&c).unwrap(),
            }
        })
        .collect();
    (scen, full_x0)
}

/// Which joint filter a stdin line asks for (see the module docs).
#[derive(Clone, Copy, PartialEq)]
enum Joint {
    /// The leader velocity a random-walk state.
    Free,
    /// Told the true leader inputs.
    Oracle,
    /// The formation-holding prior on both velocities.
    Held,
    /// The formation-holding prior on `v1` only.
    HeldV,
}

impl Joint {
    /// The leader velocity of state `z` given the follower's inputs `u`; the oracle's is
    /// `told`.
    fn velocity(self, z: &SVector<f64, 8>, u: &Vector2<f64>, told: Vector2<f64>) -> Vector2<f64> {
        let (hv, hw) = hold_at(z[3], z[4], z[5], u);
        match self {
            Joint::Oracle => told,
            Joint::Held => Vector2::new(hv + z[6], hw + z[7]),
            Joint::HeldV => Vector2::new(hv + z[6], z[7]),
            Joint::Free => Vector2::new(z[6], z[7]),
        }
    }

    /// The initial values of the last two state components.
    fn initial(self, s0: &formation_sim::scenario::Sample, pw0: f64) -> (f64, f64) {
        match self {
            Joint::Oracle => (s0.leader_inputs.v, s0.leader_inputs.w),
            Joint::Held => (0.0, 0.0),
            Joint::HeldV => (0.0, hold(s0).1),
            Joint::Free if pw0 < 0.5 => hold(s0),
            Joint::Free => (0.0, 0.0),
        }
    }

    fn label(self) -> &'static str {
        match self {
            Joint::Oracle => "ORACLE",
            Joint::Held => "HELD",
            Joint::HeldV => "HELD_V",
            Joint::Free => "JOINT",
        }
    }
}

fn main() {
    let (scen, full_x0) = scenarios();
    let x0 = [full_x0[3], full_x0[4], full_x0[5]];
    for b in [Baseline::RANDOM_WALK, Baseline::CONSTANT_VELOCITY] {
        let r: Vec<[f64; 3]> = scen.iter().map(|s| baseline(s, &x0, b)).collect();
        println!(
            "{b:?}: {:.3e} {:.3e} {:.3e}",
            median(r.iter().map(|x| x[0]).collect()),
            median(r.iter().map(|x| x[1]).collect()),
            median(r.iter().map(|x| x[2]).collect())
        );
    }
    let stdin = std::io::stdin();
    for line in std::io::BufRead::lines(stdin.lock()) {
        let line = line.unwrap();
        let mut v: Vec<f64> = line
            .split_whitespace()
            .map(|x| x.parse().unwrap())
            .collect();
        // The oracle: the joint filter told the true leader inputs at every step.
        let oracle = v.len() == 1;
        if oracle {
            v = vec![0.0, 0.0, v[0], 1e-12, 1.0];
        }
        // The formation-holding prior: the leader velocity is the one that holds the current
        // formation given the follower's inputs, plus a random-walk deviation `[dv, dw]`
        // (the last two state components), `Rr_dv Rr_dw Pdelta0`.
        let held = v.len() == 3;
        if held {
            v = vec![v[0], v[1], 1e-9, v[2], 1.0];
        }
        // Only `v1` from the formation-holding prior (`l12` held), `w1` a free random walk:
        // `Rr_dv Rr_w Pdelta0`, plus a dummy fourth number.
        let held_v = v.len() == 4;
        if held_v {
            v = vec![v[0], v[1], 1e-9, v[2], 1.0];
        }
        let mode = match (oracle, held, held_v) {
            (true, _, _) => Joint::Oracle,
            (_, true, _) => Joint::Held,
            (_, _, true) => Joint::HeldV,
            _ => Joint::Free,
        };
        if v.len() == 5 {
            run_joint(&scen, &full_x0, &v, mode, &line);
        } else if v.len() >= 11 {
            run_dual(&scen, &v, &line);
        }
    }
}

/// One joint-UKF configuration (`Rr_v Rr_w Q_formation Pw0 ut_alpha`) over the scenarios.
fn run_joint(
    scen: &[formation_sim::scenario::Scenario],
    full_x0: &[f64; 6],
    v: &[f64],
    mode: Joint,
    line: &str,
) {
    // joint: rrv rrw qform pw0 alpha
    let model = unicycle::PolarModel::new(0.5).unwrap();
    let mut ls = vec![];
    let mut as_ = vec![];
    let mut bs = vec![];
    let mut vr = vec![];
    let mut wr = vec![];
    let steps = scen[0].samples.len() - 1;
    let mut nis_sum = vec![0.0; steps];
    let mut nees_sum = vec![0.0; steps];
    let mut neesw_sum = vec![0.0; steps];
    for sc in scen {
        let mut z0 = SVector::<f64, 8>::zeros();
        for i in 0..6 {
            z0[i] = full_x0[i];
        }
        (z0[6], z0[7]) = mode.initial(&sc.samples[0], v[3]);
        let p0 = SMatrix::<f64, 8, 8>::from_diagonal(&SVector::<f64, 8>::from_row_slice(&[
            0.01, 0.01, 0.01, 0.0049, 0.0009, 0.0009, v[3], v[3],
        ]));
        let space = dukf::AngleMask::<8>::from_indices(&[2, 4, 5]).unwrap();
        let mspace = dukf::AngleMask::<3>::from_indices(&[1, 2]).unwrap();
        let mut ukf = dukf::Ukf::new(z0, p0, space, dukf::UtParams::new(v[4], 2.0, 0.0))
            .unwrap_or_else(|e| panic!("z0 {z0:?}: {e}"));
        let q = SMatrix::<f64, 8, 8>::from_diagonal(&SVector::<f64, 8>::from_row_slice(&[
            1e-6, 1e-6, 1e-6, v[2], v[2], v[2], v[0], v[1],
        ]));
        let r = sc.config.noise_covariance();
        let (mut el, mut ea, mut eb, mut ev, mut ew, mut late) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
        for (k, pair) in sc.samples.windows(2).enumerate() {
            let (prev, now) = (&pair[0], &pair[1]);
            let u: Vector2<f64> = prev.follower_inputs.into();
            ukf.predict(
                |z| {
                    let x = unicycle::PolarState::from_row_slice(&z.as_slice()[..6]);
                    let w = mode.velocity(z, &u, prev.leader_inputs.into());
                    let nx = model
                        .f(&x, &u, &w, 1.0 / 30.0)
                        .unwrap_or(unicycle::PolarState::repeat(f64::NAN));
                    let mut o = *z;
                    for i in 0..6 {
                        o[i] = nx[i];
                    }
                    o
                },
                &q,
            )
            .unwrap();
            let rep = ukf
                .update(
                    &now.measurement,
                    |z| nalgebra::Vector3::new(z[3], z[4], z[5]),
                    &r,
                    &mspace,
                )
                .unwrap();
            let z = ukf.state();
            let t = unicycle::PolarModel::h(&now.truth);
            let e = nalgebra::Vector3::new(
                z[3] - t[0],
                unicycle::wrap_angle(z[4] - t[1]),
                unicycle::wrap_angle(z[5] - t[2]),
            );
            el += e[0] * e[0];
            ea += e[1] * e[1];
            eb += e[2] * e[2];
            let est = mode.velocity(z, &u, Vector2::new(z[6], z[7]));
            let (ev_, ew_) = (est[0], est[1]);
            let dv = ev_ - prev.leader_inputs.v;
            let dw = ew_ - prev.leader_inputs.w;
            if now.t > 2.0 {
                ev += dv * dv;
                ew += dw * dw;
                late += 1.0;
            }
            let pc = ukf.covariance();
            let px = pc.fixed_view::<3, 3>(3, 3).into_owned();
            let pw = pc.fixed_view::<2, 2>(6, 6).into_owned();
            let ewv = Vector2::new(dv, dw);
            nis_sum[k] += rep.nis / scen.len() as f64;
            nees_sum[k] += e.dot(&(px.try_inverse().unwrap() * e)) / scen.len() as f64;
            neesw_sum[k] += ewv.dot(&(pw.try_inverse().unwrap() * ewv)) / scen.len() as f64;
        }
        ls.push(el / steps as f64);
        as_.push(ea / steps as f64);
        bs.push(eb / steps as f64);
        vr.push((ev / late).sqrt());
        wr.push((ew / late).sqrt());
    }
    let inside = |v: &Vec<f64>, lo: f64, hi: f64| {
        v[60..].iter().filter(|&&x| x >= lo && x <= hi).count() as f64 / (v.len() - 60) as f64
    };
    let mean = |v: &Vec<f64>| v[60..].iter().sum::<f64>() / (v.len() - 60) as f64;
    println!(
        "{} {line} | l {:.3e} a {:.3e} b {:.3e} | v {:.4} w {:.4} | late NIS {:.2} ({:.0}%) NEESx {:.2} ({:.0}%) NEESw {:.2} ({:.0}%)",
        mode.label(),
        median(ls),
        median(as_),
        median(bs),
        median(vr),
        median(wr),
        mean(&nis_sum),
        100.0 * inside(&nis_sum, 2.02, 4.17),
        mean(&nees_sum),
        100.0 * inside(&nees_sum, 2.02, 4.17),
        mean(&neesw_sum),
        100.0 * inside(&neesw_sum, 1.22, 2.97)
    );
}

/// One dual-UKF configuration (11 numbers) over the scenarios.
fn run_dual(scen: &[formation_sim::scenario::Scenario], v: &[f64], line: &str) {
    let mut cfg = paper_filter_config_with(0.5, 1.0 / 30.0, FilterDesign::Dual);
    cfg.tuning.rr = Matrix2::from_diagonal(&Vector2::new(v[0], v[1]));
    cfg.tuning.q = SMatrix::<f64, 6, 6>::from_diagonal(&SVector::<f64, 6>::from_row_slice(&[
        v[5], v[5], v[5], v[2], v[3], v[4],
    ]));
    cfg.tuning.pw0 = Matrix2::from_diagonal(&Vector2::new(v[6], v[7]));
    cfg.tuning.propagate_parameter_uncertainty = v[8] > 0.5;
    cfg.tuning.ut = dukf::UtParams::new(v[9], 2.0, 0.0);
    let p0s = v[10];
    let d = cfg.tuning.p0.diagonal();
    cfg.tuning.p0 = SMatrix::<f64, 6, 6>::from_diagonal(&SVector::<f64, 6>::from_row_slice(&[
        d[0] * p0s,
        d[1] * p0s,
        d[2] * p0s,
        d[3],
        d[4],
        d[5],
    ]));
    let runs: Vec<_> = match scen
        .iter()
        .map(|s| {
            let mut cfg = cfg.clone();
            if v[6] < 0.5 {
                let (a, b) = hold(&s.samples[0]);
                cfg.tuning.w0 = Vector2::new(a, b);
            }
            run_filter(s, &cfg)
        })
        .collect::<Result<Vec<_>, _>>()
    {
        Ok(r) => r,
        Err(e) => {
            println!("{line}: ERR {e}");
            return;
        }
    };
    let m = |f: &dyn Fn(&formation_sim::reproduce::Summary) -> f64| {
        median(runs.iter().map(|r| f(&r.summary)).collect())
    };
    let n = runs[0].consistency.len();
    let avg = |f: &dyn Fn(&formation_sim::reproduce::StepConsistency) -> f64, from: usize| {
        let mut tot = 0.0;
        let mut cnt = 0.0;
        for k in from..n {
            let a: f64 = runs.iter().map(|r| f(&r.consistency[k])).sum::<f64>() / runs.len() as f64;
            tot += a;
            cnt += 1.0;
        }
        tot / cnt
    };
    println!(
        "{line} | l {:.3e} a {:.3e} b {:.3e} | v {:.4} w {:.4} | NIS {:.2} NEESx {:.2} NEESw {:.2} (after 2s: {:.2} {:.2} {:.2})",
        m(&|s| s.mse.l12),
        m(&|s| s.mse.alpha12),
        m(&|s| s.mse.beta12),
        m(&|s| s.rms_v1_after_2s),
        m(&|s| s.rms_w1_after_2s),
        avg(&|c| c.nis, 0),
        avg(&|c| c.nees_formation, 0),
        avg(&|c| c.nees_velocity, 0),
        avg(&|c| c.nis, 60),
        avg(&|c| c.nees_formation, 60),
        avg(&|c| c.nees_velocity, 60)
    );
}

/// Leader velocity that holds the formation given the follower's inputs and x0.
fn hold(s0: &formation_sim::scenario::Sample) -> (f64, f64) {
    let u = Vector2::new(s0.follower_inputs.v, s0.follower_inputs.w);
    hold_at(PAPER_X0[3], PAPER_X0[4], PAPER_X0[5], &u)
}

/// Leader velocity `[v1, w1]` that keeps `l12` and `alpha12` constant at `(l, a, b)` given
/// the follower's inputs `u`.
fn hold_at(l: f64, a: f64, b: f64, u: &Vector2<f64>) -> (f64, f64) {
    let (v2, w2) = (u[0], u[1]);
    let d = 0.5;
    let v1 = (v2 * b.cos() + d * w2 * b.sin()) / a.cos();
    let w1 = (-v1 * a.sin() + v2 * b.sin()) / l - d * w2 * b.cos() / l;
    (v1, w1)
}
