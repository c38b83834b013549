//! Tracking a constant-turn target whose speed and turn rate are unknown, with the dual UKF.
//!
//! A target drives a circle (`v = 1.2 m/s`, `w = 0.4 rad/s`, so its heading crosses `+-pi`
//! every lap). A sensor at the origin measures range, bearing and the target's heading at
//! 20 Hz with noise, and loses the target for one second in every five (predict-only
//! frames). The dual filter estimates the state `[x, y, heading]` and the parameters
//! `[v, w]`; a plain UKF with the same noise settings but the parameters frozen at the
//! initial guess shows what the parameter filter buys.
//!
//! Run with `cargo run -p formation-dukf --example constant_turn`.

use core::f64::consts::PI;

use dukf::{AngleMask, DualUkf, Euclidean, Ukf, UkfError, UtParams, wrap_angle};
use nalgebra::{Matrix2, Matrix3, Vector2, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

const DT: f64 = 0.05;

/// One step of the constant-turn model with parameters `w = [speed, turn rate]`.
fn f(x: &Vector3<f64>, w: &Vector2<f64>) -> Vector3<f64> {
    let (s, c) = x[2].sin_cos();
    Vector3::new(x[0] + DT * w[0] * c, x[1] + DT * w[0] * s, x[2] + DT * w[1])
}

/// Range, bearing and heading.
fn h(x: &Vector3<f64>) -> Vector3<f64> {
    Vector3::new(x[0].hypot(x[1]), x[1].atan2(x[0]), x[2])
}

fn main() -> Result<(), UkfError> {
    let truth_w = Vector2::new(1.2, 0.4);
    let mut truth = Vector3::new(4.0, 0.0, PI / 2.0);

    let state_space = AngleMask::new([false, false, true]);
    let measurement_space = AngleMask::new([false, true, true]);
    let x0 = Vector3::new(3.7, 0.3, 1.3);
    let p0 = Matrix3::from_diagonal(&Vector3::new(0.1, 0.1, 0.1));
    let w0 = Vector2::new(0.5, 0.0);
    let q = Matrix3::identity() * 1e-6;
    let rr = Matrix2::identity() * 1e-6;
    let sigma = Vector3::new(0.02, 0.01, 0.05);
    let r = Matrix3::from_diagonal(&sigma.component_mul(&sigma));

    let state = Ukf::new(x0, p0, state_space, UtParams::default())?;
    let params = Ukf::new(w0, Matrix2::identity(), Euclidean, UtParams::default())?;
    let mut dual = DualUkf::new(state, params, q, rr, measurement_space)?;
    // The baseline: the same state filter, parameters frozen at the initial guess.
    let mut frozen = Ukf::new(x0, p0, state_space, UtParams::default())?;

    let mut rng = ChaCha8Rng::seed_from_u64(2024);
    let noise = [
        Normal::new(0.0, sigma[0]).expect("valid sigma"),
        Normal::new(0.0, sigma[1]).expect("valid sigma"),
        Normal::new(0.0, sigma[2]).expect("valid sigma"),
    ];

    let steps = 1200; // 60 s
    let settle = 400; // errors are accumulated after the first 20 s (20 frames a second)
    let (mut se_pos, mut se_head, mut se_pos_frozen, mut se_v, mut se_w) =
        (0.0, 0.0, 0.0, 0.0, 0.0);
    let mut coasted = 0;
    println!("   t [s]   v^ [m/s]   w^ [rad/s]   position error [m]   (frozen-parameter UKF)");
    for k in 0..steps {
        truth = f(&truth, &truth_w);
        truth[2] = wrap_angle(truth[2]);
        #[allow(clippy::cast_precision_loss)]
        let t = (k + 1) as f64 * DT;
        let occluded = (t % 5.0) >= 4.0;
        if occluded {
            dual.predict_only(f)?;
            frozen.predict(|x| f(x, &w0), &q)?;
            coasted += 1;
        } else {
            let m = h(&truth);
            let y = Vector3::new(
                m[0] + noise[0].sample(&mut rng),
                wrap_angle(m[1] + noise[1].sample(&mut rng)),
                wrap_angle(m[2] + noise[2].sample(&mut rng)),
            );
            dual.step(f, h, &y, &r)?;
            frozen.predict(|x| f(x, &w0), &q)?;
            frozen.update(&y, h, &r, &measurement_space)?;
        }
        let pos_err = (dual.state().xy() - truth.xy()).norm();
        let pos_err_frozen = (frozen.state().xy() - truth.xy()).norm();
        if k >= settle {
            se_pos += pos_err * pos_err;
            se_pos_frozen += pos_err_frozen * pos_err_frozen;
            se_head += wrap_angle(dual.state()[2] - truth[2]).powi(2);
            se_v += (dual.parameters()[0] - truth_w[0]).powi(2);
            se_w += (dual.parameters()[1] - truth_w[1]).powi(2);
        }
        if (k + 1) % 100 == 0 {
            let w = dual.parameters();
            println!(
                "{t:8.1}   {:8.4}   {:10.4}   {pos_err:18.4}   ({pos_err_frozen:.4})",
                w[0], w[1]
            );
        }
    }
    #[allow(clippy::cast_precision_loss)]
    let n = (steps - settle) as f64;
    println!();
    println!(
        "after {} s ({coasted} of {steps} frames predict-only):",
        settle / 20
    );
    println!(
        "  RMS position error, dual UKF:            {:.4} m",
        (se_pos / n).sqrt()
    );
    println!(
        "  RMS position error, frozen parameters:   {:.4} m",
        (se_pos_frozen / n).sqrt()
    );
    println!(
        "  RMS heading error, dual UKF:             {:.4} rad",
        (se_head / n).sqrt()
    );
    println!(
        "  RMS speed error:                         {:.4} m/s (truth {})",
        (se_v / n).sqrt(),
        truth_w[0]
    );
    println!(
        "  RMS turn-rate error:                     {:.4} rad/s (truth {})",
        (se_w / n).sqrt(),
        truth_w[1]
    );
    Ok(())
}
