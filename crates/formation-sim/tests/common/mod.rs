//! Helpers shared by the tracker tests.

use formation_tracker::mount::CameraMount;

/// The leader's pose (rig frame -> camera frame) for world poses of both robots.
pub fn camera_pose(
    leader: &unicycle::PlanarPose,
    follower: &unicycle::PlanarPose,
    mount: &CameraMount,
) -> pose::Pose {
    // The leader in the follower's body frame.
    let (s, c) = follower.theta.sin_cos();
    let (dx, dy) = (leader.x - follower.x, leader.y - follower.y);
    let (r, t) = mount.leader_to_camera(
        c * dx + s * dy,
        -s * dx + c * dy,
        leader.theta - follower.theta,
    );
    pose::Pose::from_matrix(r.matrix(), t)
}
