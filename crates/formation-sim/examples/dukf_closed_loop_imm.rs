//! Issue #15, measurement 13 of `docs/dukf-reproduction.md`: the IMM told the follower's
//! controller, *in the closed loop* of measurement 7 (as on a robot: the follower's
//! separation-bearing controller gets the filter's own estimates of the formation for feedback
//! and of `(v1, w1)` for feed-forward). Model B then reads back the velocity the controller was
//! given, which is the filter's own estimate: the follower's inputs carry nothing new.
//!
//! ```text
//! cargo run --release -p formation-sim --example dukf_closed_loop_imm [-- FIRST LAST]
//! ```
//! Prints, for the in-loop filter told the controller and for the same loop with the filter
//! not told it (`run_filter_with(.., false)`'s model set), the medians over the seeds of the
//! MSEs of `l12`, `alpha12`, `beta12` and the RMS velocity errors after 2 s, and the means
//! after 2 s of the formation and velocity NEES (averaged over the seeds per step, then over
//! the steps) and of NIS.
#![allow(clippy::unwrap_used)]

use formation_filter::FormationFilter;
use formation_sim::reproduce::paper_filter_config;
use formation_sim::scenario::ScenarioConfig;
use formation_sim::scenario::reference_leader_inputs;
use nalgebra::Vector2;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use unicycle::{
    ControllerConfig, Formation, Inputs, PolarModel, SeparationBearingController, wrap_angle,
};

#[path = "common/median.rs"]
mod median;
use median::median;

/// One closed-loop run: `[mse l12, alpha12, beta12, rms v1, rms w1 after 2 s]` and, per step
/// after 2 s, `[NIS, formation NEES, velocity NEES]`.
fn run(seed: u64, told: bool) -> ([f64; 5], Vec<[f64; 3]>) {
    let config = ScenarioConfig::reference(seed);
    let model = PolarModel::new(config.d).unwrap();
    let start = Formation::from_poses(&config.leader0, &config.follower0, config.d).unwrap();
    let goal = ControllerConfig::hold(&start);
    let controller = SeparationBearingController::new(config.d, goal).unwrap();
    let mut filter = FormationFilter::new(&paper_filter_config(config.d, config.dt)).unwrap();
    let noise: Vec<Normal<f64>> = config
        .noise_std
        .iter()
        .map(|&s| Normal::new(0.0, s).unwrap())
        .collect();
    let mut rng = ChaCha8Rng::seed_from_u64(config.seed);
    let r = config.noise_covariance();
    let (mut leader, mut follower) = (config.leader0, config.follower0);
    let mut prev: Option<(Inputs, Inputs)> = None;
    let (mut se, mut n, mut sv, mut nv) = ([0.0; 3], 0.0, [0.0; 2], 0.0);
    let mut stats = Vec::new();
    for k in 0..=config.steps() {
        let t = k as f64 * config.dt;
        let truth = model.state_from_poses(&leader, &follower).unwrap();
        let mut y = PolarModel::h(&truth);
        for i in 0..3 {
            y[i] += noise[i].sample(&mut rng);
        }
        let y = formation_filter::MEASUREMENT_SPACE.normalize(&y);
        if let Some((u1_prev, u2_prev)) = prev {
            if told {
                filter.set_follower_controller(Some(goal)).unwrap();
            }
            filter.step(&y, &r, u2_prev).unwrap();
            let h = PolarModel::h(&truth);
            let est = PolarModel::h(filter.state());
            let e = nalgebra::Vector3::new(
                est[0] - h[0],
                wrap_angle(est[1] - h[1]),
                wrap_angle(est[2] - h[2]),
            );
            for i in 0..3 {
                se[i] += e[i] * e[i];
            }
            n += 1.0;
            let w = filter.leader_velocity();
            let ew = Vector2::new(w.v - u1_prev.v, w.w - u1_prev.w);
            if t > 2.0 {
                sv[0] += ew[0] * ew[0];
                sv[1] += ew[1] * ew[1];
                nv += 1.0;
                let px = filter
                    .state_covariance()
                    .fixed_view::<3, 3>(3, 3)
                    .into_owned();
                let pw = *filter.leader_velocity_covariance();
                stats.push([
                    filter.last_nis().unwrap(),
                    e.dot(&(px.try_inverse().unwrap() * e)),
                    ew.dot(&(pw.try_inverse().unwrap() * ew)),
                ]);
            }
        }
        let u1 = reference_leader_inputs(t);
        // The controller sees only the filter's estimates.
        let u2 = controller
            .inputs(&filter.formation(), filter.leader_velocity())
            .unwrap();
        prev = Some((u1, u2));
        leader = leader.integrate_exact(u1, config.dt).unwrap();
        follower = follower.integrate_exact(u2, config.dt).unwrap();
    }
    (
        [
            se[0] / n,
            se[1] / n,
            se[2] / n,
            (sv[0] / nv).sqrt(),
            (sv[1] / nv).sqrt(),
        ],
        stats,
    )
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
    for told in [true, false] {
        let runs: Vec<([f64; 5], Vec<[f64; 3]>)> = (lo..=hi).map(|s| run(s, told)).collect();
        let m = |i: usize| median(runs.iter().map(|r| r.0[i]).collect());
        let steps = runs[0].1.len();
        let late = |j: usize| {
            (0..steps)
                .map(|k| runs.iter().map(|r| r.1[k][j]).sum::<f64>() / runs.len() as f64)
                .sum::<f64>()
                / steps as f64
        };
        println!(
            "{:<22} l12 {:.3e} alpha12 {:.3e} beta12 {:.3e} | rms v1 {:.4} w1 {:.4} | NIS {:.2} NEESf {:.2} NEESv {:.2}",
            if told {
                "told the controller"
            } else {
                "not told"
            },
            m(0),
            m(1),
            m(2),
            m(3),
            m(4),
            late(0),
            late(1),
            late(2)
        );
    }
}
