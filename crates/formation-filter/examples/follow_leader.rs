//! One leader tracked by the formation filter: the leader drives a slow curve at 0.8 m/s, the
//! follower drives straight at 0.8 m/s, and the filter sees the formation variables with
//! 1 cm / 10 mrad noise at 30 Hz, with every tenth frame missing. It prints, once a second,
//! the true and estimated separation and the leader's estimated velocities.
//!
//! Run with `cargo run -p formation-filter --example follow_leader`.

use formation_filter::{FilterConfig, FilterDesign, FormationFilter};
use nalgebra::{Matrix3, Vector3};
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use unicycle::{Formation, Inputs, PlanarPose, PolarModel};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let (d, dt) = (0.5, 1.0 / 30.0);
    let mut leader = PlanarPose::new(1.5, 0.25, 0.0);
    let mut follower = PlanarPose::new(0.0, 0.0, 0.0);
    let (u1, u2) = (Inputs::new(0.8, 0.05), Inputs::new(0.8, 0.0));
    let x0 = PolarModel::new(d)?.state_from_poses(&leader, &follower)?;
    let mut config = FilterConfig::new(d, dt, x0);
    config.tuning.design = FilterDesign::Imm;
    let mut filter = FormationFilter::new(&config)?;
    let std = Vector3::new(0.01, 0.01, 0.01);
    let r = Matrix3::from_diagonal(&std.component_mul(&std));
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
    let noise = Normal::new(0.0, 1.0)?;
    println!("t [s]   true l12 [m]   est l12 [m]   est v1 [m/s]   est w1 [rad/s]");
    for k in 1..=300 {
        leader = leader.integrate_exact(u1, dt)?;
        follower = follower.integrate_exact(u2, dt)?;
        let truth = Formation::from_poses(&leader, &follower, d)?;
        if k % 10 == 0 {
            filter.predict_only(u2)?;
        } else {
            let e = Vector3::from_fn(|i, _| std[i] * noise.sample(&mut rng));
            filter.step(&(truth.to_vector() + e), &r, u2)?;
        }
        if k % 30 == 0 {
            let (f, v) = (filter.formation(), filter.leader_velocity());
            let t = f64::from(k) * dt;
            println!(
                "{t:5.1} {:14.4} {:13.4} {:14.3} {:16.3}",
                truth.l12, f.l12, v.v, v.w
            );
        }
    }
    Ok(())
}
