//! Issue #15: where the IMM's consistency goes, model by model and component by component.
//! For one scenario file (or the reference), over a range of seeds, the mean over the steps
//! after t = 2 s (`FROM_T` sets another time) and over the seeds of: the model
//! probabilities; per model (A, B, C) and for the combined estimate, the normalised squared
//! error `e_i^2 / P_ii` of each of `[l12, alpha12, beta12, v1, w1]` (1 expected), the
//! formation NEES (3) and the velocity NEES (2), then the mean squared errors and the mean
//! variances of the five; the combined NIS (3); the combined NEES split along the
//! covariance's principal directions; and the combined estimate's correlations between the
//! five, predicted and from the errors. No smoother runs, so it is fast.
//!
//! ```text
//! cargo run --release -p formation-sim --example dukf_nees_probe [-- FILE|reference [FIRST LAST]]
//! ```
//! The IMM is told the follower's controller as in `reproduce dukf` (`FOLLOWER=0`: not told);
//! the tuning overrides of `dukf_imm` apply (`JERK`, `SOJOURN`, `HELD`, `MU0`, `FQ`, `CFQ`),
//! and `UT_ALPHA` (the unscented transform's spread).
#![allow(clippy::unwrap_used)]

use formation_filter::{FilterConfig, FormationFilter};
use formation_sim::scenario::{Scenario, ScenarioConfig, simulate};
use formation_sim::scenario_file::ScenarioSpec;
use nalgebra::{SMatrix, SVector, Vector2, Vector3};
use unicycle::{PolarModel, wrap_angle};

#[path = "common/imm_tuning.rs"]
mod imm_tuning;
use imm_tuning::{env, tune};

/// `[e_i^2 / P_ii for l12, alpha12, beta12, v1, w1, NEES formation, NEES velocity, e_l^2,
/// P_ll]` of one estimate.
fn stats(z: &SVector<f64, 10>, p: &SMatrix<f64, 10, 10>, truth: &SVector<f64, 5>) -> [f64; 17] {
    let mut e = SVector::<f64, 5>::zeros();
    e[0] = z[3] - truth[0];
    e[1] = wrap_angle(z[4] - truth[1]);
    e[2] = wrap_angle(z[5] - truth[2]);
    e[3] = z[6] - truth[3];
    e[4] = z[7] - truth[4];
    let mut out = [0.0; 17];
    for i in 0..5 {
        out[i] = e[i] * e[i] / p[(3 + i, 3 + i)];
    }
    let ef: Vector3<f64> = e.fixed_rows::<3>(0).into_owned();
    let pf = p.fixed_view::<3, 3>(3, 3).into_owned();
    out[5] = ef.dot(&(pf.try_inverse().unwrap() * ef));
    let ev: Vector2<f64> = e.fixed_rows::<2>(3).into_owned();
    let pv = p.fixed_view::<2, 2>(6, 6).into_owned();
    out[6] = ev.dot(&(pv.try_inverse().unwrap() * ev));
    for i in 0..5 {
        out[7 + i] = e[i] * e[i];
        out[12 + i] = p[(3 + i, 3 + i)];
    }
    out
}

/// The component pairs whose correlations are printed (indices into `[l12, alpha12, beta12,
/// v1, w1]`).
const PAIRS: [(usize, usize); 10] = [
    (0, 1),
    (0, 2),
    (1, 2),
    (3, 4),
    (0, 3),
    (0, 4),
    (1, 3),
    (1, 4),
    (2, 3),
    (2, 4),
];

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let file = args.first().filter(|a| *a != "reference").cloned();
    let lo: u64 = args.get(1).map_or(1, |a| a.parse().unwrap());
    let hi: u64 = args.get(2).map_or(20, |a| a.parse().unwrap());
    let from_t = env("FROM_T").unwrap_or(2.0);
    let follower = std::env::var("FOLLOWER").map_or(true, |v| v != "0");
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
    // Rows: A, B, C, combined; 9 statistics each; plus mu[3] and NIS.
    let mut acc = [[0.0f64; 17]; 4];
    let mut mu_acc = [0.0f64; 3];
    let mut nis_acc = 0.0;
    let mut corr = [[0.0f64; 2]; PAIRS.len()];
    let mut principal = [0.0f64; 5];
    let mut n = 0.0;
    for (s, cfg) in &runs {
        let mut cfg = cfg.clone();
        if std::env::var("X0Y").is_ok() {
            // Start at the first measurement (its noise is the prior's P0).
            for i in 0..3 {
                cfg.x0[3 + i] = s.samples[0].measurement[i];
            }
        }
        let mut f = FormationFilter::new(&cfg).unwrap();
        let r = s.config.noise_covariance();
        for pair in s.samples.windows(2) {
            let (prev, now) = (&pair[0], &pair[1]);
            if follower {
                f.set_follower_controller(Some(prev.controller)).unwrap();
            }
            f.step(&now.measurement, &r, prev.follower_inputs).unwrap();
            if now.t <= from_t {
                continue;
            }
            let h = PolarModel::h(&now.truth);
            let truth = SVector::<f64, 5>::from_row_slice(&[
                h[0],
                h[1],
                h[2],
                prev.leader_inputs.v,
                prev.leader_inputs.w,
            ]);
            let models = f.model_estimates().unwrap();
            for (j, (z, p)) in models.iter().enumerate() {
                let st = stats(z, p, &truth);
                for i in 0..17 {
                    acc[j][i] += st[i];
                }
            }
            let mut z = SVector::<f64, 10>::zeros();
            z.fixed_rows_mut::<6>(0).copy_from(f.state());
            let w = f.leader_velocity();
            z[6] = w.v;
            z[7] = w.w;
            let mut p = SMatrix::<f64, 10, 10>::identity();
            p.fixed_view_mut::<6, 6>(0, 0)
                .copy_from(f.state_covariance());
            let c5 = f.estimate_covariance();
            p.fixed_view_mut::<5, 5>(3, 3).copy_from(&c5);
            let st = stats(&z, &p, &truth);
            for i in 0..17 {
                acc[3][i] += st[i];
            }
            // Correlations of the combined estimate: predicted P_ij / sqrt(P_ii P_jj) against
            // the normalised product of the errors e_i e_j / sqrt(P_ii P_jj).
            let e = SVector::<f64, 5>::from_fn(|i, _| {
                let d = z[3 + i] - truth[i];
                if i == 1 || i == 2 { wrap_angle(d) } else { d }
            });
            for (k, &(i, j)) in PAIRS.iter().enumerate() {
                let norm = (p[(3 + i, 3 + i)] * p[(3 + j, 3 + j)]).sqrt();
                corr[k][0] += p[(3 + i, 3 + j)] / norm;
                corr[k][1] += e[i] * e[j] / norm;
            }
            // The NEES split along the covariance's principal directions (smallest variance
            // first): each term is 1 on average when consistent.
            let pf = p.fixed_view::<3, 3>(3, 3).into_owned();
            let ef: nalgebra::Vector3<f64> = e.fixed_rows::<3>(0).into_owned();
            let eig = pf.symmetric_eigen();
            let mut order: Vec<usize> = (0..3).collect();
            order.sort_by(|&a, &b| eig.eigenvalues[a].total_cmp(&eig.eigenvalues[b]));
            for (slot, &i) in order.iter().enumerate() {
                let u = eig.eigenvectors.column(i);
                principal[slot] += u.dot(&ef).powi(2) / eig.eigenvalues[i];
            }
            let pv = p.fixed_view::<2, 2>(6, 6).into_owned();
            let ev: Vector2<f64> = e.fixed_rows::<2>(3).into_owned();
            let eig = pv.symmetric_eigen();
            let (lo, hi) = if eig.eigenvalues[0] <= eig.eigenvalues[1] {
                (0, 1)
            } else {
                (1, 0)
            };
            for (slot, i) in [(3, lo), (4, hi)] {
                let u = eig.eigenvectors.column(i);
                principal[slot] += u.dot(&ev).powi(2) / eig.eigenvalues[i];
            }
            let mu = f.model_probabilities().unwrap();
            for j in 0..3 {
                mu_acc[j] += mu[j];
            }
            nis_acc += f.last_nis().unwrap();
            n += 1.0;
        }
    }
    println!(
        "mu A {:.3} B {:.3} C {:.3}  NIS {:.2}",
        mu_acc[0] / n,
        mu_acc[1] / n,
        mu_acc[2] / n,
        nis_acc / n
    );
    println!(
        "model      l12  alpha12  beta12     v1     w1  NEESf  NEESv | mse l12 a12 b12 v1 w1 | P l12 a12 b12 v1 w1"
    );
    for (name, a) in ["A", "B", "C", "comb"].iter().zip(&acc) {
        println!(
            "{name:5} {:7.2} {:7.2} {:7.2} {:6.2} {:6.2} {:6.2} {:6.2} | {}",
            a[0] / n,
            a[1] / n,
            a[2] / n,
            a[3] / n,
            a[4] / n,
            a[5] / n,
            a[6] / n,
            a[7..17]
                .iter()
                .map(|v| format!("{:.1e}", v / n))
                .collect::<Vec<_>>()
                .join(" ")
        );
    }
    let names = ["l12", "alpha12", "beta12", "v1", "w1"];
    println!(
        "combined NEES along the principal directions, formation (smallest variance first) {:.2} {:.2} {:.2}, velocity {:.2} {:.2}",
        principal[0] / n,
        principal[1] / n,
        principal[2] / n,
        principal[3] / n,
        principal[4] / n
    );
    println!("combined correlations (predicted, from the errors):");
    for (k, &(i, j)) in PAIRS.iter().enumerate() {
        println!(
            "  {}-{}: {:+.3} {:+.3}",
            names[i],
            names[j],
            corr[k][0] / n,
            corr[k][1] / n
        );
    }
}
