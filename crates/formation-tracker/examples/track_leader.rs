//! Tracks one leader from per-frame pose measurements, the way a robot's vision loop feeds
//! the tracker: a leader drives straight ahead of a follower that stands still, each frame's
//! pose (rig frame to camera frame) comes with a covariance, and the tracker estimates the
//! formation variables and the leader's unknown velocity.
//!
//! Run with `cargo run -p formation-tracker --example track_leader`.

use formation_tracker::mount::CameraMount;
use formation_tracker::tracker::{
    FrameInput, Observation, PoseMeasurement, Tracker, TrackerConfig,
};
use nalgebra::{Matrix6, Vector6};
use unicycle::Inputs;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    const DT: f64 = 1.0 / 30.0;
    const V1: f64 = 0.3; // the leader's speed, unknown to the tracker
    let mount = CameraMount::default();
    let mut tracker = Tracker::new(TrackerConfig::reference(mount.offset, DT))?;
    // A joint pose's typical standard deviations: rotation vector (rad), translation (m).
    let sigma = Vector6::new(0.01, 0.01, 0.01, 0.003, 0.003, 0.01);
    let covariance = Matrix6::from_diagonal(&sigma.component_mul(&sigma));
    for k in 0..=150 {
        let t = k as f64 * DT;
        // The leader on the floor, in the follower's body frame: 1.5 m ahead, 0.25 m left.
        let (rotation, translation) = mount.leader_to_camera(1.5 + V1 * t, 0.25, 0.0);
        let estimate = pose::Estimate {
            pose: pose::Pose::from_matrix(rotation.matrix(), translation),
            rms: 0.1,
            covariance,
            iterations: 3,
            converged: true,
        };
        let frame = FrameInput {
            t,
            follower: Inputs::new(0.0, 0.0),
            mount,
            observations: vec![Observation {
                robot: 1,
                points: 8,
                pose: PoseMeasurement::Chosen(estimate),
            }],
        };
        let report = tracker.update(&frame)?;
        if k % 30 == 0 {
            for l in &report.leaders {
                println!(
                    "t {t:.1} s  robot {} {:?}: l12 {:.3} m  alpha12 {:.3} rad  v1 {:.2} m/s (true {V1})",
                    l.robot, l.status, l.formation.l12, l.formation.alpha12, l.v1
                );
            }
        }
    }
    Ok(())
}
