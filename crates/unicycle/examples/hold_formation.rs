//! A follower holds formation behind a leader that weaves, using the separation-bearing
//! controller on the true formation variables. Prints the l12 and alpha12 errors over time.
//!
//! Run with `cargo run -p formation-unicycle --example hold_formation`.

use unicycle::{
    ControllerConfig, Formation, Inputs, PlanarPose, SeparationBearingController, UnicycleError,
    wrap_angle,
};

fn main() -> Result<(), UnicycleError> {
    let d = 0.5;
    let dt = 1.0 / 30.0;
    let mut leader = PlanarPose::new(1.5, 0.25, 0.0);
    let mut follower = PlanarPose::new(0.0, 0.0, 0.0);
    let start = Formation::from_poses(&leader, &follower, d)?;
    // Ask for 20 cm more separation than at the start, same bearing.
    let config = ControllerConfig {
        l12_desired: start.l12 + 0.2,
        ..ControllerConfig::hold(&start)
    };
    let controller = SeparationBearingController::new(d, config)?;
    println!("    t [s]   l12 error [m]   alpha12 error [rad]   v2 [m/s]   w2 [rad/s]");
    for k in 0..=240 {
        let t = k as f64 * dt;
        let u1 = Inputs::new(0.8 + 0.2 * (0.5 * t).sin(), 0.2 * (0.4 * t).sin());
        let f = Formation::from_poses(&leader, &follower, d)?;
        let u2 = controller.inputs(&f, u1)?;
        if k % 30 == 0 {
            println!(
                "{t:9.2} {:15.5} {:21.5} {:10.3} {:12.3}",
                config.l12_desired - f.l12,
                wrap_angle(config.alpha12_desired - f.alpha12),
                u2.v,
                u2.w
            );
        }
        leader = leader.integrate_exact(u1, dt)?;
        follower = follower.integrate_exact(u2, dt)?;
    }
    Ok(())
}
