//! The paper's dual-UKF experiment (Figs. 12-13) from the library, without the CLI:
//! simulate the reference scenario for a few seeds and print what the filter buys over the
//! raw measurements.
//!
//! Run with `cargo run --release -p formation-sim --example dual_ukf`.

use formation_sim::reproduce::reproduce;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    println!("seed  MSE l12 (filter / raw)   MSE alpha12 (filter / raw)   RMS v1, w1 after 2 s");
    for seed in 1..=5 {
        let s = reproduce(seed, false)?.summary;
        println!(
            "{seed:>4}  {:.2e} / {:.2e}       {:.2e} / {:.2e}           {:.3} m/s, {:.3} rad/s",
            s.mse.l12,
            s.mse.meas_l12,
            s.mse.alpha12,
            s.mse.meas_alpha12,
            s.rms_v1_after_2s,
            s.rms_w1_after_2s
        );
    }
    Ok(())
}
