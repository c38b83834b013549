//! Issue #15: where the IMM loses, second by second. For one scenario file (or the reference),
//! averages over seeds per 1-s bin: the model probabilities [A, B, C], the squared `alpha12`
//! and `l12` errors of the IMM, the true leader turn rate, the range of the true `alpha12`,
//! the velocity and formation NEES, the RMS `w1` error, the mean true `alpha12`, the mean
//! `alpha12` error (bias) and the mean error of model B's turn rate at the *true* state
//! (`formation_holding_velocity(truth, u2) - w1`). No smoother runs, so it is fast.
//!
//! ```text
//! cargo run --release -p formation-sim --example dukf_imm_probe [-- FILE [FIRST LAST]]
//! ```
//! The tuning overrides of `dukf_imm` apply (`JERK`, `SOJOURN`, `HELD`, `MU0`, `FQ`).
#![allow(clippy::unwrap_used)]

use formation_filter::{FilterConfig, FormationFilter};
use formation_sim::scenario::{Scenario, ScenarioConfig, simulate};
use formation_sim::scenario_file::ScenarioSpec;
use nalgebra::Vector2;
use unicycle::PolarModel;
use unicycle::formation_holding_velocity;

#[path = "common/imm_tuning.rs"]
mod imm_tuning;
use imm_tuning::tune;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let file = args.first().filter(|a| *a != "reference").cloned();
    let lo: u64 = args.get(1).map_or(1, |a| a.parse().unwrap());
    let hi: u64 = args.get(2).map_or(20, |a| a.parse().unwrap());
    let runs: Vec<(Scenario, FilterConfig)> = (lo..=hi)
        .map(|seed| match &file {
            Some(f) => {
                let spec = ScenarioSpec::load(std::path::Path::new(f)).unwrap();
                let mut cfg = spec.filter_config();
                tune(&mut cfg);
                (spec.simulate(seed, false).unwrap(), cfg)
            }
            None => {
                let c = ScenarioConfig::reference(seed);
                let mut cfg = formation_sim::reproduce::paper_filter_config(c.d, c.dt);
                tune(&mut cfg);
                (simulate(&c).unwrap(), cfg)
            }
        })
        .collect();
    // Per bin: count, mu[3], e_alpha^2, e_l^2, w1 true, alpha true min/max, nees_v, nees_f.
    let bins = runs[0].0.config.duration.ceil() as usize + 1;
    let mut acc = vec![[0.0f64; 14]; bins];
    let mut amin = vec![f64::INFINITY; bins];
    let mut amax = vec![f64::NEG_INFINITY; bins];
    for (s, cfg) in &runs {
        let mut f = FormationFilter::new(cfg).unwrap();
        let r = s.config.noise_covariance();
        for pair in s.samples.windows(2) {
            let (prev, now) = (&pair[0], &pair[1]);
            f.step(&now.measurement, &r, prev.follower_inputs).unwrap();
            let b = now.t.floor() as usize;
            let mu = f.model_probabilities().unwrap();
            let truth = PolarModel::h(&now.truth);
            let est = PolarModel::h(f.state());
            let w = f.leader_velocity();
            let ew = Vector2::new(w.v - prev.leader_inputs.v, w.w - prev.leader_inputs.w);
            let pw = *f.leader_velocity_covariance();
            let nees_v = ew.dot(&(pw.try_inverse().unwrap() * ew));
            let ex = est - truth;
            let px = f.state_covariance().fixed_view::<3, 3>(3, 3).into_owned();
            let nees_f = ex.dot(&(px.try_inverse().unwrap() * ex));
            let a = &mut acc[b];
            a[0] += 1.0;
            a[1] += mu[0];
            a[2] += mu[1];
            a[3] += mu[2];
            a[4] += (est[1] - truth[1]).powi(2);
            a[5] += (est[0] - truth[0]).powi(2);
            a[6] += prev.leader_inputs.w;
            a[7] += nees_v;
            a[8] += nees_f;
            a[9] += (w.w - prev.leader_inputs.w).powi(2);
            a[10] += truth[1];
            a[11] += est[1] - truth[1];
            // Model B's velocity at the true state: the follower's inputs include its
            // controller's correction, so it is not the leader's velocity.
            let u2: Vector2<f64> = prev.follower_inputs.into();
            a[12] +=
                formation_holding_velocity(&prev.truth, &u2, s.config.d)[1] - prev.leader_inputs.w;
            // Model B's own velocity NEES.
            let (wb, pb) = f.model_velocities().unwrap()[1];
            let eb = wb - Vector2::new(prev.leader_inputs.v, prev.leader_inputs.w);
            a[13] += eb.dot(&(pb.try_inverse().unwrap() * eb));
            amin[b] = amin[b].min(truth[1]);
            amax[b] = amax[b].max(truth[1]);
        }
    }
    println!(
        " t   muA   muB   muC  mse_a12   mse_l12   w1true  a12range  NEESv NEESf rms_w1  a12true  a12bias  holdw1err"
    );
    let mut tot = [0.0f64; 14];
    for (k, a) in acc.iter().enumerate() {
        if a[0] == 0.0 {
            continue;
        }
        for i in 0..14 {
            tot[i] += a[i];
        }
        let n = a[0];
        println!(
            "{k:2} {:.3} {:.3} {:.3} {:.2e} {:.2e} {:+.3} {:.2e} {:5.2} {:5.2} {:.4} {:.5} {:+.2e} {:+.2e} {:5.2}",
            a[1] / n,
            a[2] / n,
            a[3] / n,
            a[4] / n,
            a[5] / n,
            a[6] / n,
            amax[k] - amin[k],
            a[7] / n,
            a[8] / n,
            (a[9] / n).sqrt(),
            a[10] / n,
            a[11] / n,
            a[12] / n,
            a[13] / n
        );
    }
    let n = tot[0];
    println!(
        "all mean mse_a12 {:.3e} mse_l12 {:.3e} NEESv {:.2} NEESf {:.2} NEESv(B) {:.2}",
        tot[4] / n,
        tot[5] / n,
        tot[7] / n,
        tot[8] / n,
        tot[13] / n
    );
}
