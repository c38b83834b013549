//! The pose of one square (or rectangular) marker from its four corners: what OpenCV users
//! get from `aruco::estimatePoseSingleMarkers` or `solvePnP(..., SOLVEPNP_IPPE_SQUARE)`.
//!
//! **Conventions are OpenCV's**, so results compare one to one: corners in the order top-left
//! (as printed), top-right, bottom-right, bottom-left, pixel centres at integer coordinates;
//! the marker frame has its origin at the marker's centre, `x` to the right, `y` up and `z`
//! out of the printed face, so the corners are `(-w/2, h/2, 0)`, `(w/2, h/2, 0)`,
//! `(w/2, -h/2, 0)`, `(-w/2, -h/2, 0)` ([`marker_corners`]). The pose maps marker points into
//! the camera frame (rotation vector and translation, metres).
//!
//! The solve is [`PoseSolver::planar_candidates`]: corners undistorted with the solver's
//! lens model, IPPE's two planar candidates in closed form, each refined by
//! Levenberg-Marquardt; the better is [`MarkerPose::best`], the other
//! [`MarkerPose::alternative`] (a marker seen nearly face-on at a distance has two poses
//! that fit almost equally well: the "flip").

use crate::{Estimate, PoseError, PoseSolver};
use nalgebra::{Point2, Point3};

/// The 3D corners of a `width x height` marker (metres; a square marker has `width ==
/// height`, its side) in OpenCV's marker frame and corner order (see the module docs).
pub fn marker_corners(width: f64, height: f64) -> Result<[Point3<f64>; 4], PoseError> {
    if !(width.is_finite() && height.is_finite() && width > 0.0 && height > 0.0) {
        return Err(PoseError::InvalidMarkerSize { width, height });
    }
    let (x, y) = (width / 2.0, height / 2.0);
    Ok([
        Point3::new(-x, y, 0.0),
        Point3::new(x, y, 0.0),
        Point3::new(x, -y, 0.0),
        Point3::new(-x, -y, 0.0),
    ])
}

/// The pose of one marker: both planar candidates, best first.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MarkerPose {
    /// The candidate with the lower reprojection RMS: marker frame to camera frame, its RMS
    /// (pixels, over the four undistorted corners) and its 6x6 covariance of
    /// `[wx, wy, wz, tx, ty, tz]` (see [`Estimate`]).
    pub best: Estimate,
    /// The other IPPE candidate after its own refinement. When only one candidate could be
    /// refined (the other put the marker behind the camera) it is `best` again.
    pub alternative: Estimate,
}

impl MarkerPose {
    /// The alternative's RMS over the best's (>= 1; near 1 the flip fits almost as well).
    /// `None` when the alternative is the same pose (rotation within 1e-6 rad).
    pub fn ambiguity_ratio(&self) -> Option<f64> {
        if self.alternative.pose.rotation_angle_to(&self.best.pose) < 1e-6 {
            return None;
        }
        Some(self.alternative.rms / self.best.rms.max(f64::MIN_POSITIVE))
    }
}

impl PoseSolver {
    /// The pose of a `side x side` square marker (metres) from its four pixel corners in
    /// OpenCV's order (see the module docs). The corners are the detected (distorted) ones:
    /// the solver's distortion model ([`PoseSolver::with_distortion`]) is applied first.
    ///
    /// # Errors
    /// [`PoseError::InvalidMarkerSize`] for a side that is not positive and finite, and the
    /// errors of [`PoseSolver::planar_candidates`] (non-finite corners, undistortion that
    /// fails, a degenerate quad, no candidate in front of the camera).
    pub fn solve_square_marker(
        &self,
        corners: &[Point2<f64>; 4],
        side: f64,
    ) -> Result<MarkerPose, PoseError> {
        self.solve_marker(corners, side, side)
    }

    /// [`PoseSolver::solve_square_marker`] for a rectangular `width x height` marker (`width`
    /// along the top edge, from the first corner to the second).
    pub fn solve_marker(
        &self,
        corners: &[Point2<f64>; 4],
        width: f64,
        height: f64,
    ) -> Result<MarkerPose, PoseError> {
        let model = marker_corners(width, height)?;
        let [best, alternative] = self.planar_candidates(&model, corners)?;
        Ok(MarkerPose { best, alternative })
    }
}
