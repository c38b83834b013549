//! The single-marker pose stage of `formation-tracker detect`: `--marker-size [ID=]METRES`
//! (with `--camera`) gives each marker of a known size a `pose` in the JSON output, as
//! OpenCV's `estimatePoseSingleMarkers` / `solvePnP(IPPE_SQUARE)` would (marker frame: origin
//! at the centre, x right, y up, z out of the printed face; see `docs/outputs.md`).
//!
//! Sizes: `--marker-size 0.065` for every marker, `--marker-size 12=0.15` for the marker of
//! dictionary index 12 (it wins over the default), and `WxH` (`0.14x0.12`) for a rectangular
//! marker, width along its top edge. A pose that cannot be right (reprojection far above the
//! corner noise, the marker behind the camera) or that fails is reported in `rejected` with
//! the reason and the marker's `pose` is `null`.

use pose::Camera;
use pose::{MarkerPose, PoseSolver};
use serde::Serialize;

/// A reprojection RMS above this (pixels) cannot be right for a marker the detector read: its
/// corners are good to a few tenths of a pixel (the robot stage uses the same bound).
pub const MAX_REPROJECTION_PX: f64 = 3.0;

/// One `--marker-size` value: `[ID=]SIZE` with `SIZE` metres or `WxH` metres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MarkerSize {
    /// The dictionary index it applies to; `None` for the default.
    pub index: Option<usize>,
    /// Width (along the top edge), metres.
    pub width: f64,
    /// Height, metres.
    pub height: f64,
}

/// Parses `0.065`, `12=0.15` or `0.14x0.12` (clap value parser: an error exits with code 2).
pub fn parse_marker_size(s: &str) -> Result<MarkerSize, String> {
    let (index, size) = match s.split_once('=') {
        Some((id, size)) => {
            let id = id.trim().parse::<usize>().map_err(|_| {
                format!("`{id}` is not a marker id (a dictionary index, 0 or more)")
            })?;
            (Some(id), size)
        }
        None => (None, s),
    };
    let side = |t: &str| {
        let m = super::numbers::positive(t)
            .map_err(|e| format!("marker size `{t}` {e} (metres, e.g. 0.065 or 12=0.15)"))?;
        // A printed marker is between a millimetre and 100 m (1e308 made every pose fail).
        if (1e-3..=super::numbers::MAX_METRES).contains(&m) {
            Ok(m)
        } else {
            Err(format!(
                "marker size `{t}` m is not a printed marker's (1 mm to 100 m; metres, e.g. 0.065)"
            ))
        }
    };
    let (width, height) = match size.split_once(['x', 'X']) {
        Some((w, h)) => (side(w)?, side(h)?),
        None => {
            let s = side(size)?;
            (s, s)
        }
    };
    Ok(MarkerSize {
        index,
        width,
        height,
    })
}

/// The sizes given, looked up by dictionary index.
#[derive(Debug, Clone, Default)]
pub struct MarkerSizes {
    default: Option<(f64, f64)>,
    by_index: Vec<(usize, (f64, f64))>,
}

impl MarkerSizes {
    /// From the `--marker-size` values; a later value for the same id (or the default) wins.
    pub fn new(values: &[MarkerSize]) -> Self {
        let mut sizes = Self::default();
        for v in values {
            let wh = (v.width, v.height);
            match v.index {
                None => sizes.default = Some(wh),
                Some(i) => {
                    sizes.by_index.retain(|(j, _)| *j != i);
                    sizes.by_index.push((i, wh));
                }
            }
        }
        sizes
    }

    /// True when no size was given (no marker gets a pose).
    pub fn is_empty(&self) -> bool {
        self.default.is_none() && self.by_index.is_empty()
    }

    /// The size of the marker with this dictionary index, metres.
    pub fn of(&self, index: usize) -> Option<(f64, f64)> {
        self.by_index
            .iter()
            .find(|(i, _)| *i == index)
            .map(|(_, wh)| *wh)
            .or(self.default)
    }
}

/// One pose candidate in the JSON output.
#[derive(Debug, Serialize)]
pub struct CandidateOut {
    /// Rotation vector, marker frame to camera frame, radians.
    pub rotation: [f64; 3],
    /// The marker's centre in the camera frame, metres.
    pub translation: [f64; 3],
    /// RMS over the four corners as detected, pixels.
    pub reprojection_rms_px: f64,
}

/// A marker's `pose` in the JSON output.
#[derive(Debug, Serialize)]
pub struct MarkerPoseOut {
    /// Rotation vector, marker frame to camera frame, radians.
    pub rotation: [f64; 3],
    /// The marker's centre in the camera frame, metres.
    pub translation: [f64; 3],
    /// RMS over the four corners as detected, pixels.
    pub reprojection_rms_px: f64,
    /// The other planar candidate (the "flip"); equal to the pose when there is none.
    pub alternative: CandidateOut,
    /// 6x6 covariance of `[wx, wy, wz, tx, ty, tz]`, row-major (rad^2, rad m, m^2).
    pub covariance: [[f64; 6]; 6],
}

impl From<&MarkerPose> for MarkerPoseOut {
    fn from(m: &MarkerPose) -> Self {
        let c = &m.best.covariance;
        Self {
            rotation: m.best.pose.rotation.into(),
            translation: m.best.pose.translation.into(),
            reprojection_rms_px: m.best.rms,
            alternative: CandidateOut {
                rotation: m.alternative.pose.rotation.into(),
                translation: m.alternative.pose.translation.into(),
                reprojection_rms_px: m.alternative.rms,
            },
            covariance: std::array::from_fn(|r| std::array::from_fn(|k| c[(r, k)])),
        }
    }
}

/// The pose of the marker of dictionary index `index` from its detected corners (NW, NE, SE,
/// SW as printed: OpenCV's order), or why there is none. `Ok(None)` when no size is known
/// for it.
pub fn marker_pose(
    calibration: &Camera,
    sizes: &MarkerSizes,
    index: usize,
    corners: &fiducial::Corners,
) -> Result<Option<MarkerPoseOut>, String> {
    let Some((w, h)) = sizes.of(index) else {
        return Ok(None);
    };
    let solver = PoseSolver::new(calibration.intrinsics).with_distortion(calibration.distortion);
    let m = solver
        .solve_marker(corners, w, h)
        .map_err(|e| format!("marker {index}: pose failed: {e}"))?;
    let b = &m.best;
    if !(b.pose.is_finite() && b.rms.is_finite() && b.covariance.iter().all(|v| v.is_finite())) {
        return Err(format!("marker {index}: pose rejected: not finite"));
    }
    if b.rms > MAX_REPROJECTION_PX {
        return Err(format!(
            "marker {index}: pose rejected: reprojection {:.1} px above {MAX_REPROJECTION_PX} px",
            b.rms
        ));
    }
    if b.pose.translation.z <= 0.0 {
        return Err(format!(
            "marker {index}: pose rejected: behind the camera (z = {:.3} m)",
            b.pose.translation.z
        ));
    }
    Ok(Some(MarkerPoseOut::from(&m)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse_and_the_per_id_size_wins() {
        let v: Vec<MarkerSize> = ["0.065", "12=0.15", "3=0.14x0.12"]
            .iter()
            .map(|s| parse_marker_size(s).unwrap())
            .collect();
        let sizes = MarkerSizes::new(&v);
        assert_eq!(sizes.of(0), Some((0.065, 0.065)));
        assert_eq!(sizes.of(12), Some((0.15, 0.15)));
        assert_eq!(sizes.of(3), Some((0.14, 0.12)));
        assert!(MarkerSizes::new(&v[1..]).of(0).is_none());
        for bad in ["0", "-0.1", "nan", "x=0.1", "12=", "0.1x", "abc"] {
            let e = parse_marker_size(bad).unwrap_err();
            assert!(!e.is_empty(), "{bad}");
        }
        assert!(parse_marker_size("inf").unwrap_err().contains("metres"));
    }

    #[test]
    fn a_quad_no_square_can_project_to_is_rejected_with_the_reason() {
        let calibration = Camera::from_yaml_str(
            "image_width: 640\nimage_height: 480\ncamera_matrix: {rows: 3, cols: 3, data: [554, 0, 319.5, 0, 554, 239.5, 0, 0, 1]}\n",
        )
        .unwrap();
        let sizes = MarkerSizes::new(&[parse_marker_size("0.1").unwrap()]);
        let p = |x: f64, y: f64| nalgebra::Point2::new(x, y);
        // A square seen frontally gets a pose...
        let square = [
            p(300.0, 200.0),
            p(340.0, 200.0),
            p(340.0, 240.0),
            p(300.0, 240.0),
        ];
        let ok = marker_pose(&calibration, &sizes, 4, &square)
            .unwrap()
            .unwrap();
        assert!(ok.reprojection_rms_px < 1e-6 && ok.translation[2] > 0.0);
        // ...a kite with one long arm does not.
        let kite = [
            p(300.0, 200.0),
            p(340.0, 200.0),
            p(460.0, 380.0),
            p(300.0, 240.0),
        ];
        let e = marker_pose(&calibration, &sizes, 4, &kite).unwrap_err();
        assert!(e.starts_with("marker 4: pose"), "{e}");
        assert!(e.contains("reprojection") || e.contains("failed"), "{e}");
    }
}
