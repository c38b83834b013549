//! `formation-tracker detect IMAGE... [--json] [--dictionary NAME]...`: finds and reads the
//! markers in image files, of our own dictionary or of the named standard ones.
//!
//! Each image (PNG or JPEG, any colour type, converted to 8-bit grey) goes through one reused
//! `fiducial::Detector`. With `--json`, one JSON object per image, one per line, with the
//! image's path and size, the markers read (`dictionary` and `id`; for our own dictionary
//! also code, robot and face from the rig mapping; Hamming distance corrected, sub-pixel
//! corners from the marker's top-left as printed, clockwise, in pixel-centre convention),
//! `robots` (with `--camera`: one joint pose per robot and its formation variables, see
//! `detect_robots.rs`; empty otherwise), with `--marker-size` each marker's own `pose`
//! (`marker_pose.rs`; `null` otherwise) and `timing.detect_ms`: the
//! detector's own time for the image, decoding excluded (quad finding: the stage times of
//! `Detector::stats` up to the decoding). Without `--json`, a short listing. An unreadable file gets one
//! error line on stderr and the others are still processed; the exit code is then non-zero.

use std::path::PathBuf;

use clap::Args as ClapArgs;
use fiducial::{Decoded, Detector, DetectorConfig, GrayView};
use formation_tracker::rig::RigModel;
use formation_tracker::robots::{FaceRejection, RobotMeasurement};
use serde::Serialize;
use unicycle::Formation;

use super::CliError;

/// Arguments of `formation-tracker detect`.
#[derive(Debug, ClapArgs)]
pub struct Args {
    /// Images to read (PNG or JPEG).
    #[arg(required = true)]
    pub images: Vec<PathBuf>,
    /// Print one JSON object per image (one line each) instead of a listing.
    #[arg(long)]
    pub json: bool,
    /// Marker dictionary to read, by name (case-insensitive): `FORMATION_4X5` (our own, the
    /// default), an OpenCV name such as `DICT_4X4_50` or `DICT_APRILTAG_36h11`, or an
    /// AprilTag name such as `tag36h11`. Repeat it to read several dictionaries in one pass.
    #[arg(long = "dictionary", value_name = "NAME")]
    pub dictionaries: Vec<String>,
    /// Do not search large dark regions that gave no quad by AprilTag 3's boundary
    /// clustering. It is on by default in `detect` (photographs, where recall matters more
    /// than milliseconds): it reads tags that touch something as dark as their ink (a tag
    /// lying on a dark floor or against a shadow, as 1 of the 56 Duckietown tags does), and
    /// costs about 3 ms more per 640x480 real frame, 2-4x the time on cluttered frames
    /// (docs/marker-families.md). The library's `DetectorConfig::default()` and `track`
    /// keep it off.
    #[arg(long)]
    pub no_boundary_clusters: bool,
    /// The default since boundary clustering is on in `detect`; kept so that older
    /// scripts still run.
    #[arg(long, hide = true, conflicts_with = "no_boundary_clusters")]
    pub boundary_clusters: bool,
    /// Do not read quads again as motion-blurred markers (on by default: a quad whose
    /// cells are not a code, with a marker's border and edges smeared by at least 1.5
    /// cells, is re-read with its cell levels solved for the motion; and dark regions up
    /// to 160 px that gave no quad are cut again nearer the white level, where a smeared
    /// marker's outline is closed). Turning it off saves time on frames that are never
    /// blurred.
    #[arg(long)]
    pub no_motion_blur: bool,
    /// Fit the corners of markers whose cells are under 3 px to the whole modelled marker
    /// (cells, quiet zone, surround, light gradient, blur), as `track` and `demo` do: it
    /// removes the edge rules' bias on small cells (0.07-0.12 px per corner, more on
    /// oblique faces), which matters when the corners feed a pose, and costs 0.5-2 ms per
    /// marker fitted. Off by default, as in the library's `DetectorConfig::default()`.
    #[arg(long)]
    pub photometric: bool,
    /// Largest image side accepted, pixels; larger images are refused from their header,
    /// before they are decoded.
    #[arg(long, value_name = "PX", default_value_t = formation_io::frames::MAX_SIDE,
          value_parser = super::numbers::max_side)]
    pub max_side: usize,
    /// Size of the markers, metres, for a `pose` per marker (needs `--camera`):
    /// `--marker-size 0.065` for all, `--marker-size 12=0.15` for dictionary index 12,
    /// `WxH` for a rectangular marker. Repeat as needed.
    #[arg(long, value_name = "[ID=]METRES", requires = "camera", allow_hyphen_values = true,
          value_parser = super::marker_pose::parse_marker_size)]
    pub marker_size: Vec<super::marker_pose::MarkerSize>,
    /// The robot stage: `--camera`, `--rig`, `--pan`, `--mount`, `--free-pose`.
    #[command(flatten)]
    pub robots: super::detect_robots::RobotArgs,
}

/// One marker in the JSON output. Own-dictionary markers keep `code`, `robot` and `face`
/// (and their historical field order); every marker has `dictionary` and `id`.
#[derive(Debug, Serialize)]
struct MarkerOut {
    /// The code (own dictionary only).
    #[serde(skip_serializing_if = "Option::is_none")]
    code: Option<u64>,
    /// Dictionary index (= `id`).
    index: usize,
    /// Robot from the rig mapping (own dictionary, or the rig's dictionary).
    #[serde(skip_serializing_if = "Option::is_none")]
    robot: Option<u32>,
    /// Face from the rig mapping (as `robot`).
    #[serde(skip_serializing_if = "Option::is_none")]
    face: Option<u8>,
    hamming: u32,
    /// First corner = the marker's top-left as printed, then clockwise (OpenCV's order);
    /// pixel centres at integer coordinates.
    corners: [[f64; 2]; 4],
    contrast: f64,
    /// With `--marker-size`: the marker's own pose (`null` without a size or when rejected).
    pose: Option<super::marker_pose::MarkerPoseOut>,
    /// The dictionary's name, e.g. `FORMATION_4X5` or `DICT_APRILTAG_36h11`.
    dictionary: &'static str,
    /// The marker's id in that dictionary (OpenCV's / AprilTag's id).
    id: usize,
}

/// One robot in the JSON output (with `--camera`), built from the library's
/// [`RobotMeasurement`]. The field names and their order are the command's output format:
/// keep them when the library's type changes.
#[derive(Debug, Serialize)]
struct RobotOut {
    robot: u32,
    /// Faces used for the pose.
    faces: Vec<u8>,
    /// Faces read but rejected as inconsistent with the others.
    rejected_faces: Vec<u8>,
    /// The same faces, each with the reason it was dropped.
    rejections: Vec<FaceRejection>,
    /// Rotation vector, rig frame to camera frame (radians).
    rotation: [f64; 3],
    /// Rig origin in the camera frame (metres).
    translation: [f64; 3],
    reprojection_rms_px: f64,
    /// `l12`, `alpha12`, `beta12`, flat in the record.
    #[serde(flatten)]
    formation: Formation,
    /// Covariance of `(l12, alpha12, beta12)`.
    covariance: [[f64; 3]; 3],
    ambiguous: bool,
    /// `null` unless a single face left two candidates.
    ambiguity_ratio: Option<f64>,
    ground_plane: bool,
}

impl From<&RobotMeasurement> for RobotOut {
    fn from(m: &RobotMeasurement) -> Self {
        Self {
            robot: m.robot,
            faces: m.faces.clone(),
            rejected_faces: m.rejected_faces.clone(),
            rejections: m.rejections.clone(),
            rotation: m.rotation,
            translation: m.translation,
            reprojection_rms_px: m.reprojection_rms_px,
            formation: m.formation,
            covariance: m.covariance,
            ambiguous: m.ambiguous,
            ambiguity_ratio: m.ambiguity_ratio,
            ground_plane: m.ground_plane,
        }
    }
}

/// Timing of one image.
#[derive(Debug, Serialize)]
struct Timing {
    /// Quad finding (binarize, components, contours, quads, sub-pixel corners), decoding
    /// excluded, in milliseconds.
    detect_ms: f64,
    /// Decoding of the quads found, in milliseconds.
    decode_ms: f64,
}

/// One line of the JSON output.
#[derive(Debug, Serialize)]
struct ImageOut {
    image: String,
    width: usize,
    height: usize,
    markers: Vec<MarkerOut>,
    /// Robots seen (rig pose per robot), with `--camera`; empty otherwise.
    robots: Vec<RobotOut>,
    /// Robots whose markers were read but whose pose failed or cannot be right
    /// (reprojection, range, floor), with the reason; they are not in `robots`.
    rejected: Vec<RejectedOut>,
    timing: Timing,
}

#[derive(Debug, Serialize)]
struct RejectedOut {
    /// The robot, when the failure is about one.
    robot: Option<u32>,
    /// The marker's dictionary index, for a rejected single-marker pose (absent otherwise).
    #[serde(skip_serializing_if = "Option::is_none")]
    marker: Option<usize>,
    /// Why, e.g. `robot 1: pose rejected: reprojection 49.0 px above 3 px`.
    reason: String,
}

fn marker_out(d: &Decoded, dictionary: &'static str, rig: &RigModel) -> MarkerOut {
    let own = dictionary == fiducial::PAPER_NAME;
    // An own-dictionary code on no face of the rig's table is reported as robot 0, face 0
    // (as always); other dictionaries' markers carry a robot and face only on the rig's.
    let (robot, face) = match rig.robot_face_in(dictionary, d.index) {
        Some((r, f)) => (Some(r), Some(f)),
        None if own => (Some(0), Some(0)),
        None => (None, None),
    };
    MarkerOut {
        code: own.then_some(d.code),
        index: d.index,
        robot,
        face,
        hamming: d.distance,
        corners: d.corners.map(|p| [p.x, p.y]),
        contrast: d.contrast,
        pose: None,
        dictionary,
        id: d.index,
    }
}

/// The dictionaries named by `--dictionary` (default: the rig's, which is our own unless
/// the rig file names another), without repeats.
fn dictionaries(
    names: &[String],
    rig: &RigModel,
) -> Result<Vec<&'static fiducial::Dictionary>, CliError> {
    let mut out: Vec<&'static fiducial::Dictionary> = Vec::new();
    if names.is_empty() {
        out.push(rig.marker_dictionary().map_err(|e| e.to_string())?);
    }
    for n in names {
        let d = fiducial::dictionary_by_name(n)
            .map_err(|e| super::Usage(format!("--dictionary {n}: {e}")))?;
        if !out.iter().any(|o| std::ptr::eq(*o, d)) {
            out.push(d);
        }
    }
    Ok(out)
}

/// What every image of a run is read with.
struct Context<'a> {
    args: &'a Args,
    stage: Option<super::detect_robots::RobotStage>,
    rig: RigModel,
    sizes: super::marker_pose::MarkerSizes,
    /// Each dictionary's standard name, in the detector's order.
    names: Vec<&'static str>,
    /// The rig's dictionary among them (the robot stage reads it only).
    rig_dict: Option<usize>,
}

/// Reads every image; reports unreadable ones on stderr and, at the end, ends with a partial
/// result (exit code 3) if some were, or an error if all were.
pub fn run(args: &Args) -> Result<(), CliError> {
    let dict = fiducial::Dictionary::paper();
    let stage = super::detect_robots::RobotStage::from_args(&args.robots, dict)?;
    let rig = match &stage {
        Some(stage) => stage.rig.clone(),
        None => super::detect_robots::RobotStage::rig(&args.robots, dict)?,
    };
    let dicts = dictionaries(&args.dictionaries, &rig)?;
    let names: Vec<&'static str> = dicts
        .iter()
        .map(|d| d.name().unwrap_or(fiducial::PAPER_NAME))
        .collect();
    let rig_dict = names.iter().position(|n| *n == rig.dictionary);
    let mut detector = Detector::with_dictionaries(
        DetectorConfig {
            boundary_clusters: !args.no_boundary_clusters,
            motion_blur: !args.no_motion_blur,
            ..if args.photometric {
                DetectorConfig::for_pose()
            } else {
                DetectorConfig::default()
            }
        },
        dicts.into_iter().cloned().collect(),
    )
    .map_err(|e| e.to_string())?;
    let context = Context {
        args,
        stage,
        rig,
        sizes: super::marker_pose::MarkerSizes::new(&args.marker_size),
        names,
        rig_dict,
    };
    let mut found = Vec::new();
    let mut failed = 0usize;
    for path in &args.images {
        match detect_image(&context, &mut detector, path, &mut found) {
            Ok(out) => write_image(args.json, &out)?,
            Err(err) => {
                super::progress::errln!("formation-tracker: error: {}: {err}", path.display());
                failed += 1;
            }
        }
    }
    let total = args.images.len();
    match failed {
        0 => Ok(()),
        f if f == total => Err(format!("none of the {total} image(s) could be read").into()),
        f => Err(super::Partial(format!("{f} of {total} image(s) could not be read")).into()),
    }
}

/// A duration in milliseconds.
fn ms(d: std::time::Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

/// One image: its markers (in every dictionary), its robots and their rejections, and with
/// `--marker-size` each marker's own pose; the error says why the image could not be read.
fn detect_image(
    c: &Context<'_>,
    detector: &mut Detector,
    path: &std::path::Path,
    found: &mut Vec<Decoded>,
) -> Result<ImageOut, String> {
    let grey = formation_io::frames::read_grey_with_max_side(path, c.args.max_side)?;
    let (w, h) = (grey.width, grey.height);
    let view = GrayView::new(&grey.data, w, h).map_err(|e| e.to_string())?;
    detector.detect(&view, found);
    let time = detector.stats().time;
    let rig_markers: Vec<Decoded> = found
        .iter()
        .filter(|d| Some(d.dictionary) == c.rig_dict)
        .copied()
        .collect();
    let (robots, mut rejected) = match &c.stage {
        None => (Vec::new(), Vec::new()),
        Some(stage) => {
            let (robots, failures) = stage
                .measure(&rig_markers, w as u32, h as u32)
                .map_err(|e| e.to_string())?;
            let rejected = failures
                .iter()
                .map(|f| RejectedOut {
                    robot: f.robot(),
                    marker: None,
                    reason: f.to_string(),
                })
                .collect();
            (robots.iter().map(RobotOut::from).collect(), rejected)
        }
    };
    let mut markers: Vec<MarkerOut> = found
        .iter()
        .map(|d| marker_out(d, c.names[d.dictionary], &c.rig))
        .collect();
    if let Some(stage) = c.stage.as_ref().filter(|_| !c.sizes.is_empty()) {
        let calibration = stage
            .calibration_for(w as u32, h as u32)
            .map_err(|e| e.to_string())?;
        for (m, d) in markers.iter_mut().zip(found.iter()) {
            match super::marker_pose::marker_pose(&calibration, &c.sizes, d.index, &d.corners) {
                Ok(pose) => m.pose = pose,
                Err(reason) => {
                    super::progress::errln!("formation-tracker: warning: {reason}");
                    rejected.push(RejectedOut {
                        robot: None,
                        marker: Some(d.index),
                        reason,
                    });
                }
            }
        }
    }
    Ok(ImageOut {
        image: path.display().to_string(),
        width: w,
        height: h,
        markers,
        robots,
        rejected,
        timing: Timing {
            detect_ms: ms(time.binarize + time.label + time.examine + time.second_look),
            decode_ms: ms(time.decode),
        },
    })
}

/// One image's output: a JSON line with `--json`, else text lines.
fn write_image(json: bool, out: &ImageOut) -> Result<(), CliError> {
    let (w, h) = (out.width, out.height);
    if json {
        super::outln!("{}", serde_json::to_string(out)?)?;
    } else {
        super::outln!(
            "{}: {}x{}, {} marker(s), detect {:.2} ms",
            out.image,
            w,
            h,
            out.markers.len(),
            out.timing.detect_ms
        )?;
        for m in &out.markers {
            let c = m.corners;
            let who = match (m.robot, m.face, m.code) {
                (Some(r), Some(f), Some(code)) => {
                    format!("robot {r} face {f} (code {code}, index {}, ", m.index)
                }
                (Some(r), Some(f), None) => {
                    format!("robot {r} face {f} ({} id {}, ", m.dictionary, m.id)
                }
                _ => format!("{} id {} (", m.dictionary, m.id),
            };
            super::outln!(
                "  {}{} bit(s) corrected) NW ({:.2}, {:.2}) NE ({:.2}, {:.2}) SE ({:.2}, {:.2}) SW ({:.2}, {:.2})",
                who,
                m.hamming,
                c[0][0],
                c[0][1],
                c[1][0],
                c[1][1],
                c[2][0],
                c[2][1],
                c[3][0],
                c[3][1]
            )?;
            if let Some(p) = &m.pose {
                let t = p.translation;
                super::outln!(
                    "    pose: centre ({:.3}, {:.3}, {:.3}) m, {:.3} m away, rotation {:.1} deg, reprojection {:.2} px",
                    t[0],
                    t[1],
                    t[2],
                    (t[0] * t[0] + t[1] * t[1] + t[2] * t[2]).sqrt(),
                    (p.rotation[0].powi(2) + p.rotation[1].powi(2) + p.rotation[2].powi(2))
                        .sqrt()
                        .to_degrees(),
                    p.reprojection_rms_px
                )?;
            }
        }
        for r in &out.robots {
            super::outln!(
                "  robot {} pose from faces {:?}: l12 {:.3} m, alpha12 {:.2} deg, beta12 {:.2} deg, reprojection {:.2} px{}",
                r.robot,
                r.faces,
                r.formation.l12,
                r.formation.alpha12.to_degrees(),
                r.formation.beta12.to_degrees(),
                r.reprojection_rms_px,
                if r.ambiguous { " (ambiguous)" } else { "" }
            )?;
        }
    }
    Ok(())
}
