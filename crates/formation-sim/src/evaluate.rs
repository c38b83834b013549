//! Scoring the whole pipeline on a synthetic scene: render, detect, group by robot, solve
//! poses, and compare with the exact ground truth.
//!
//! Every detected marker is matched to the true face at its location (the face whose
//! projected border corners are nearest, within [`MATCH_TOLERANCE`] of its width); a marker
//! whose code is not the one on that face, or that lies on no face at all, is a *wrong
//! code*. A face is *read* when a marker with its code was detected on it. A face *must be
//! read* when it is visible, seen at most [`MAX_OFF_AXIS_DEG`](crate::scene::MAX_OFF_AXIS_DEG)
//! off-axis and at least [`MIN_WIDTH_PX`](crate::scene::MIN_WIDTH_PX) wide. Pose errors
//! compare each robot's measured `(l12, alpha12, beta12)` and relative heading
//! (`beta12 - alpha12`) with the truth; the distance error is relative to the true `l12`.

use fiducial::{Decoded, Detector, DetectorConfig, Dictionary, GrayView};
use nalgebra::{Matrix3, Point2};
use serde::{Deserialize, Serialize};

use crate::scene::{RenderedScene, SceneError, SceneSpec, SceneTruth, render_scene};
use formation_tracker::rig::RigModel;
use formation_tracker::robots::{
    FaceRejection, FrameRobots, MarkerObservation, RobotConfig, measure_robots,
};
use unicycle::wrap_angle;

/// A detection matches a true face when its mean corner distance is below this fraction of
/// the face's width in pixels (or 3 px, whichever is larger).
pub const MATCH_TOLERANCE: f64 = 0.25;

/// Distance error limit of the done-when criteria, percent.
pub const MAX_DISTANCE_ERROR_PCT: f64 = 1.0;
/// Heading error limit of the done-when criteria, degrees.
pub const MAX_HEADING_ERROR_DEG: f64 = 1.0;

/// One robot of a scored scene.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RobotReport {
    /// Robot number.
    pub robot: u32,
    /// Faces visible (front-facing, in the image, unoccluded).
    pub faces_visible: Vec<u8>,
    /// Faces that must be read (visible, <= 75 deg off-axis, >= 14 px wide).
    pub faces_required: Vec<u8>,
    /// Faces read with the right code.
    pub faces_read: Vec<u8>,
    /// Faces the paper reports read (Figs. 7-9).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub paper_faces: Option<Vec<u8>>,
    /// Markers on this robot's faces read with another code, or read with this robot's code
    /// where it has no face.
    pub wrong_codes: usize,
    /// Faces used for the pose (after outlier rejection).
    pub faces_used: Vec<u8>,
    /// Faces partly hidden by an occluder ([`crate::scene::FaceTruthOut::partly_hidden`]).
    #[serde(default)]
    pub faces_partly_hidden: Vec<u8>,
    /// Faces read but dropped from the pose, with the reason.
    #[serde(default)]
    pub rejections: Vec<FaceRejection>,
    /// Mean distance of the read corners from the true ones, pixels.
    pub corner_error_px: Option<f64>,
    /// `100 |l12 - l12_true| / l12_true`.
    pub distance_error_pct: Option<f64>,
    /// `|heading - heading_true|` (wrapped), radians.
    pub heading_error: Option<f64>,
    /// `l12 - l12_true`, metres.
    pub l12_error: Option<f64>,
    /// `alpha12 - alpha12_true`, radians (wrapped).
    pub alpha12_error: Option<f64>,
    /// `beta12 - beta12_true`, radians (wrapped).
    pub beta12_error: Option<f64>,
    /// The pose came from one face with two close candidates.
    pub ambiguous: bool,
    /// Every required face read, no wrong code, and (when measured) both errors within
    /// the limits; a robot with a required face must be measured.
    pub pass: bool,
}

/// A scored scene.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SceneReport {
    /// Scene name.
    pub scene: String,
    /// Per robot.
    pub robots: Vec<RobotReport>,
    /// Detections on no robot of the scene (wrong codes not attributable to a robot).
    pub stray_codes: usize,
    /// Every robot passes and there is no stray code.
    pub pass: bool,
}

/// Everything evaluating a scene produced.
#[derive(Debug)]
pub struct Evaluation {
    /// The rendered frame and its truth.
    pub rendered: RenderedScene,
    /// The markers detected.
    pub detections: Vec<Decoded>,
    /// The robots measured.
    pub robots: FrameRobots,
    /// The score.
    pub report: SceneReport,
}

/// The camera matrix of a truth record.
pub fn truth_k(truth: &SceneTruth) -> Matrix3<f64> {
    Matrix3::from_row_slice(&truth.k.concat())
}

/// The true face under a detection: `(robot index, face index, mean corner distance)`.
fn locate(truth: &SceneTruth, corners: &[Point2<f64>; 4]) -> Option<(usize, usize, f64)> {
    let mut best: Option<(usize, usize, f64)> = None;
    for (ri, r) in truth.robots.iter().enumerate() {
        for (fi, f) in r.faces.iter().enumerate() {
            let (Some(c), Some(w)) = (f.corners_px, f.width_px) else {
                continue;
            };
            if !f.visible && f.off_axis >= std::f64::consts::FRAC_PI_2 {
                continue;
            }
            let d = c
                .iter()
                .zip(corners)
                .map(|(t, p)| (Point2::new(t[0], t[1]) - p).norm())
                .sum::<f64>()
                / 4.0;
            if d <= (MATCH_TOLERANCE * w).max(3.0) && best.is_none_or(|b| d < b.2) {
                best = Some((ri, fi, d));
            }
        }
    }
    best
}

/// Renders, detects, measures and scores `spec`. `paper_faces` are the paper's reported
/// faces per robot (robot 1, robot 2), if any.
pub fn evaluate_scene(
    spec: &SceneSpec,
    rig: &RigModel,
    dictionary: &Dictionary,
    detector: &mut Detector,
    config: &RobotConfig,
    paper_faces: Option<(&[u8], &[u8])>,
) -> Result<Evaluation, SceneError> {
    let rendered = render_scene(spec, rig, dictionary)?;
    let truth = &rendered.truth;
    let view = GrayView::new(rendered.image.as_raw(), truth.width, truth.height).map_err(|e| {
        SceneError::Field {
            field: "camera.width/height".into(),
            reason: e.to_string(),
        }
    })?;
    let mut detections = Vec::new();
    detector.detect(&view, &mut detections);

    let n = truth.robots.len();
    let mut read: Vec<Vec<u8>> = vec![Vec::new(); n];
    let mut wrong = vec![0usize; n];
    let mut corner_err: Vec<Vec<f64>> = vec![Vec::new(); n];
    let mut stray = 0;
    for d in &detections {
        match locate(truth, &d.corners) {
            Some((ri, fi, dist)) => {
                let f = &truth.robots[ri].faces[fi];
                if f.index == d.index {
                    read[ri].push(f.face);
                    corner_err[ri].push(dist);
                } else {
                    wrong[ri] += 1;
                }
            }
            None => match rig
                .robot_face(d.index)
                .and_then(|(r, _)| truth.robots.iter().position(|t| t.robot == r))
            {
                Some(ri) => wrong[ri] += 1,
                None => stray += 1,
            },
        }
    }

    let k = truth_k(truth);
    let intrinsics = pose::Intrinsics::from_matrix(&k).map_err(|e| SceneError::Field {
        field: "camera".into(),
        reason: e.to_string(),
    })?;
    let solver = pose::PoseSolver::new(intrinsics);
    let observations: Vec<MarkerObservation> = detections
        .iter()
        .map(|d| MarkerObservation {
            index: d.index,
            corners: d.corners,
        })
        .collect();
    let robots = measure_robots(&observations, rig, &solver, &spec.mount, config);

    let mut reports = Vec::with_capacity(n);
    for (ri, t) in truth.robots.iter().enumerate() {
        let faces_visible: Vec<u8> = t
            .faces
            .iter()
            .filter(|f| f.visible)
            .map(|f| f.face)
            .collect();
        let faces_required: Vec<u8> = t
            .faces
            .iter()
            .filter(|f| f.readable)
            .map(|f| f.face)
            .collect();
        let mut faces_read = read[ri].clone();
        faces_read.sort_unstable();
        faces_read.dedup();
        let m = robots.robots.iter().find(|m| m.robot == t.robot);
        let true_heading = wrap_angle(t.formation.beta12 - t.formation.alpha12);
        let distance_error_pct =
            m.map(|m| 100.0 * (m.formation.l12 - t.formation.l12).abs() / t.formation.l12);
        let heading_error = m.map(|m| wrap_angle(m.relative_heading() - true_heading).abs());
        let all_read = faces_required.iter().all(|f| faces_read.contains(f));
        let pose_ok = match (distance_error_pct, heading_error) {
            (Some(d), Some(h)) => {
                d <= MAX_DISTANCE_ERROR_PCT && h.to_degrees() <= MAX_HEADING_ERROR_DEG
            }
            _ => faces_required.is_empty(),
        };
        let corner_error_px = (!corner_err[ri].is_empty())
            .then(|| corner_err[ri].iter().sum::<f64>() / corner_err[ri].len() as f64);
        let paper = paper_faces.and_then(|(a, b)| match t.robot {
            1 => Some(a.to_vec()),
            2 => Some(b.to_vec()),
            _ => None,
        });
        reports.push(RobotReport {
            robot: t.robot,
            faces_visible,
            faces_required,
            faces_read,
            paper_faces: paper,
            wrong_codes: wrong[ri],
            faces_used: m.map(|m| m.faces.clone()).unwrap_or_default(),
            faces_partly_hidden: t
                .faces
                .iter()
                .filter(|f| f.partly_hidden)
                .map(|f| f.face)
                .collect(),
            rejections: m.map(|m| m.rejections.clone()).unwrap_or_default(),
            corner_error_px,
            distance_error_pct,
            heading_error,
            l12_error: m.map(|m| m.formation.l12 - t.formation.l12),
            alpha12_error: m.map(|m| wrap_angle(m.formation.alpha12 - t.formation.alpha12)),
            beta12_error: m.map(|m| wrap_angle(m.formation.beta12 - t.formation.beta12)),
            ambiguous: m.is_some_and(|m| m.ambiguous),
            pass: all_read && wrong[ri] == 0 && pose_ok,
        });
    }
    let pass = stray == 0 && reports.iter().all(|r| r.pass);
    Ok(Evaluation {
        report: SceneReport {
            scene: spec.name.clone(),
            robots: reports,
            stray_codes: stray,
            pass,
        },
        rendered,
        detections,
        robots,
    })
}

/// The detector used on scenes: the tracker pipeline's settings
/// ([`DetectorConfig::for_pose`]) with `dictionary`.
pub fn default_detector(dictionary: &Dictionary) -> Detector {
    Detector::with_dictionary(DetectorConfig::for_pose(), dictionary.clone())
}

fn faces(list: &[u8]) -> String {
    if list.is_empty() {
        "-".to_string()
    } else {
        list.iter().map(u8::to_string).collect::<Vec<_>>().join(",")
    }
}

fn opt(v: Option<f64>, digits: usize) -> String {
    v.map_or_else(|| "-".to_string(), |v| format!("{v:.digits$}"))
}

/// One Markdown table row per robot of every scene.
pub fn markdown_table(reports: &[SceneReport], with_paper: bool) -> String {
    let mut s = String::new();
    s.push_str("| scene | robot | faces visible | faces to read | faces read |");
    if with_paper {
        s.push_str(" paper read |");
    }
    s.push_str(
        " wrong codes | faces used | corner err (px) | distance err (%) | heading err (deg) \
         | l12 err (m) | alpha12 err (deg) | beta12 err (deg) | pass |\n|---|---|---|---|---|",
    );
    if with_paper {
        s.push_str("---|");
    }
    s.push_str("---|---|---|---|---|---|---|---|---|\n");
    for r in reports {
        for b in &r.robots {
            s.push_str(&format!(
                "| {} | {} | {} | {} | {} |",
                r.scene,
                b.robot,
                faces(&b.faces_visible),
                faces(&b.faces_required),
                faces(&b.faces_read)
            ));
            if with_paper {
                s.push_str(&format!(
                    " {} |",
                    b.paper_faces
                        .as_deref()
                        .map_or_else(|| "n/a".to_string(), faces)
                ));
            }
            s.push_str(&format!(
                " {} | {}{} | {} | {} | {} | {} | {} | {} | {} |\n",
                b.wrong_codes,
                faces(&b.faces_used),
                if b.ambiguous { " (ambiguous)" } else { "" },
                opt(b.corner_error_px, 2),
                opt(b.distance_error_pct, 3),
                opt(b.heading_error.map(f64::to_degrees), 3),
                opt(b.l12_error, 4),
                opt(b.alpha12_error.map(f64::to_degrees), 3),
                opt(b.beta12_error.map(f64::to_degrees), 3),
                if b.pass { "yes" } else { "**no**" }
            ));
        }
    }
    s
}

/// Totals over many scenes.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Summary {
    /// Scenes scored.
    pub scenes: usize,
    /// Scenes that pass.
    pub scenes_passing: usize,
    /// Robots in all scenes.
    pub robots: usize,
    /// Robots with a pose.
    pub robots_measured: usize,
    /// Faces that had to be read.
    pub faces_required: usize,
    /// Of those, read.
    pub faces_required_read: usize,
    /// Wrong codes (attributed and stray).
    pub wrong_codes: usize,
    /// Largest distance error, percent.
    pub max_distance_error_pct: f64,
    /// Largest heading error, degrees.
    pub max_heading_error_deg: f64,
    /// Mean distance error, percent.
    pub mean_distance_error_pct: f64,
    /// Mean heading error, degrees.
    pub mean_heading_error_deg: f64,
}

/// Totals of `reports`.
pub fn summarize(reports: &[SceneReport]) -> Summary {
    let mut s = Summary {
        scenes: reports.len(),
        ..Summary::default()
    };
    let (mut sum_d, mut sum_h) = (0.0, 0.0);
    for r in reports {
        s.scenes_passing += usize::from(r.pass);
        s.wrong_codes += r.stray_codes;
        for b in &r.robots {
            s.robots += 1;
            s.faces_required += b.faces_required.len();
            s.faces_required_read += b
                .faces_required
                .iter()
                .filter(|f| b.faces_read.contains(f))
                .count();
            s.wrong_codes += b.wrong_codes;
            if let (Some(d), Some(h)) = (b.distance_error_pct, b.heading_error.map(f64::to_degrees))
            {
                s.robots_measured += 1;
                s.max_distance_error_pct = s.max_distance_error_pct.max(d);
                s.max_heading_error_deg = s.max_heading_error_deg.max(h);
                sum_d += d;
                sum_h += h;
            }
        }
    }
    if s.robots_measured > 0 {
        s.mean_distance_error_pct = sum_d / s.robots_measured as f64;
        s.mean_heading_error_deg = sum_h / s.robots_measured as f64;
    }
    s
}

/// The summary as a short Markdown list.
pub fn markdown_summary(s: &Summary) -> String {
    format!(
        "- scenes passing: **{} / {}**\n- faces that had to be read: {}, read: **{}**\n\
         - wrong codes: **{}**\n- robots: {}, with a pose: {}\n\
         - distance error: mean {:.3} %, max **{:.3} %** (limit {} %)\n\
         - heading error: mean {:.3} deg, max **{:.3} deg** (limit {} deg)\n",
        s.scenes_passing,
        s.scenes,
        s.faces_required,
        s.faces_required_read,
        s.wrong_codes,
        s.robots,
        s.robots_measured,
        s.mean_distance_error_pct,
        s.max_distance_error_pct,
        MAX_DISTANCE_ERROR_PCT,
        s.mean_heading_error_deg,
        s.max_heading_error_deg,
        MAX_HEADING_ERROR_DEG
    )
}
