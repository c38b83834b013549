//! Camera calibration files: OpenCV `FileStorage` YAML and ROS `camera_info` YAML (feature
//! `calib`).
//!
//! Both formats store the same fields, so one reader serves both:
//!
//! ```yaml
//! image_width: 640
//! image_height: 480
//! camera_matrix: { rows: 3, cols: 3, data: [fx, s, cx, 0, fy, cy, 0, 0, 1] }
//! distortion_coefficients: { rows: 1, cols: 5, data: [k1, k2, p1, p2, k3] }
//! distortion_model: plumb_bob      # ROS; optional in OpenCV files
//! ```
//!
//! The distortion model ([`DistortionModel`]) is the one `distortion_model` names
//! (`plumb_bob`, `rational_polynomial`, `equidistant`; `fisheye` is taken for `equidistant`),
//! or `equidistant` when the file says `fisheye_model: 1` (as OpenCV's calibration sample
//! writes for `cv::fisheye`); without either, OpenCV's coefficient count decides: 4 or 5
//! values are `plumb_bob`, 8 `rational_polynomial` (12 or 14 with the thin-prism and tilt
//! terms zero). A fisheye calibration cannot be told from its 4 coefficients, so it must be
//! named. An empty or absent coefficient vector is no distortion, except for a fisheye lens.
//!
//! OpenCV writes the matrices as `!!opencv-matrix` nodes with an extra `dt: d` entry and starts
//! the file with `%YAML:1.0`. serde-saphyr 2 ignores unknown tags such as `!!opencv-matrix` (its
//! default, documented behaviour) and, although `%YAML:1.0` is not the YAML spelling of the
//! directive (`%YAML 1.0`), accepts that first line as it stands: the tests parse the
//! unmodified OpenCV fixture, so nothing is stripped or rewritten. The line is only used to
//! recognise the format: OpenCV when that header or a `dt` entry is present, ROS otherwise.
//! `dt` must be `d` or `f`; `data` is read as `f64` either way.
//!
//! A missing or malformed field gives [`CalibrationError::MissingField`] or
//! [`CalibrationError::BadField`] naming it.

use crate::Camera;
use crate::distortion::ProfileFault;
use crate::{Distortion, DistortionModel, Intrinsics, PoseError};
use nalgebra::Matrix3;
use serde::Deserialize;
use std::path::Path;

/// Why a calibration file could not be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum CalibrationError {
    /// The file could not be read.
    #[error("cannot read calibration file {path}: {message}")]
    Io {
        /// The path.
        path: String,
        /// The operating system's message.
        message: String,
    },
    /// The text is not YAML of the expected shape.
    #[error("calibration file is not valid YAML for a camera calibration: {message}")]
    Yaml {
        /// The parser's message (with line and column).
        message: String,
    },
    /// A required field is absent.
    #[error("calibration file has no `{field}`")]
    MissingField {
        /// The field, e.g. `camera_matrix.data`.
        field: &'static str,
    },
    /// A field is present but unusable.
    #[error("calibration field `{field}` is invalid: {reason}")]
    BadField {
        /// The field.
        field: &'static str,
        /// What is wrong with it.
        reason: String,
    },
    /// An image's size is not the calibration's. A pose solved with the wrong intrinsics is
    /// wrong by hundreds of pixels, so this is refused unless the caller asks to rescale
    /// ([`Camera::scaled_to`]).
    #[error(
        "the image is {width}x{height} but the calibration is for {calibrated_width}x{calibrated_height}"
    )]
    SizeMismatch {
        /// Image width, pixels.
        width: u32,
        /// Image height, pixels.
        height: u32,
        /// The calibration's width, pixels.
        calibrated_width: u32,
        /// The calibration's height, pixels.
        calibrated_height: u32,
    },
    /// The image cannot be a resized copy of the calibrated one: its aspect ratio differs
    /// (a crop or another sensor mode needs its own calibration), or it is empty.
    #[error(
        "a {width}x{height} image is not a resize of the calibrated {calibrated_width}x{calibrated_height} (aspect ratios differ by more than 1 %); calibrate that camera mode"
    )]
    NotAResize {
        /// Image width, pixels.
        width: u32,
        /// Image height, pixels.
        height: u32,
        /// The calibration's width, pixels.
        calibrated_width: u32,
        /// The calibration's height, pixels.
        calibrated_height: u32,
    },
}

/// Which file format a calibration came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CalibrationFormat {
    /// OpenCV `FileStorage` YAML (`%YAML:1.0`, `!!opencv-matrix`).
    OpenCv,
    /// ROS `camera_info` YAML (`distortion_model`).
    Ros,
}

#[derive(Deserialize)]
struct RawMatrix {
    rows: Option<usize>,
    cols: Option<usize>,
    dt: Option<String>,
    data: Option<Vec<f64>>,
}

#[derive(Deserialize)]
struct RawFile {
    image_width: Option<i64>,
    image_height: Option<i64>,
    camera_matrix: Option<RawMatrix>,
    distortion_coefficients: Option<RawMatrix>,
    distortion_model: Option<String>,
    fisheye_model: Option<i64>,
}

impl Camera {
    /// `Ok` if an image of `width x height` is the size this calibration was made for,
    /// else [`CalibrationError::SizeMismatch`].
    pub fn check_size(&self, width: u32, height: u32) -> Result<(), CalibrationError> {
        if (width, height) == (self.width, self.height) {
            Ok(())
        } else {
            Err(CalibrationError::SizeMismatch {
                width,
                height,
                calibrated_width: self.width,
                calibrated_height: self.height,
            })
        }
    }

    /// The same camera for its images resized to `width x height`: focal lengths scale with
    /// the size, and the principal point too, in the pixel-centre convention (`u0' = (u0 +
    /// 1/2) s - 1/2`). Distortion is in normalised coordinates and does not change. The
    /// aspect ratio must be kept to within 1 % ([`CalibrationError::NotAResize`]).
    pub fn scaled_to(&self, width: u32, height: u32) -> Result<Self, CalibrationError> {
        let not_a_resize = CalibrationError::NotAResize {
            width,
            height,
            calibrated_width: self.width,
            calibrated_height: self.height,
        };
        if (width, height) == (self.width, self.height) {
            return Ok(*self);
        }
        if width == 0 || height == 0 || self.width == 0 || self.height == 0 {
            return Err(not_a_resize);
        }
        let sx = f64::from(width) / f64::from(self.width);
        let sy = f64::from(height) / f64::from(self.height);
        if (sx / sy - 1.0).abs() > 0.01 {
            return Err(not_a_resize);
        }
        let k = &self.intrinsics;
        let intrinsics = Intrinsics::new(
            k.alpha() * sx,
            k.beta() * sy,
            k.theta(),
            (k.u0() + 0.5) * sx - 0.5,
            (k.v0() + 0.5) * sy - 0.5,
        )
        .map_err(|e| CalibrationError::BadField {
            field: "camera_matrix",
            reason: format!("scaled to {width}x{height}: {e}"),
        })?;
        Ok(Self {
            intrinsics,
            width,
            height,
            ..*self
        })
    }

    /// The largest calibration file read, bytes (1 MiB; real ones are under 2 KiB): a larger
    /// file, or `/dev/zero`, is refused before it is read whole.
    pub const MAX_FILE_BYTES: u64 = 1 << 20;

    /// Reads a calibration file (OpenCV or ROS YAML) of at most [`Self::MAX_FILE_BYTES`].
    ///
    /// # Errors
    /// [`CalibrationError::Io`] naming the file when it cannot be read or is too large;
    /// otherwise what [`Self::from_yaml_str`] refuses.
    pub fn from_file(path: impl AsRef<Path>) -> Result<Self, CalibrationError> {
        use std::io::Read as _;
        let path = path.as_ref();
        let io = |message: String| CalibrationError::Io {
            path: path.display().to_string(),
            message,
        };
        let mut bytes = Vec::new();
        std::fs::File::open(path)
            .and_then(|f| f.take(Self::MAX_FILE_BYTES + 1).read_to_end(&mut bytes))
            .map_err(|e| io(e.to_string()))?;
        if bytes.len() as u64 > Self::MAX_FILE_BYTES {
            return Err(io(format!(
                "more than {} bytes, the limit for a calibration file",
                Self::MAX_FILE_BYTES
            )));
        }
        let text = String::from_utf8(bytes).map_err(|e| {
            io(format!(
                "not UTF-8 text (invalid byte at offset {})",
                e.utf8_error().valid_up_to()
            ))
        })?;
        Self::from_yaml_str(&text)
    }

    /// Parses calibration YAML text (OpenCV or ROS).
    ///
    /// # Errors
    /// As [`Self::from_yaml_str_with_format`].
    pub fn from_yaml_str(text: &str) -> Result<Self, CalibrationError> {
        Self::from_yaml_str_with_format(text).map(|(camera, _)| camera)
    }

    /// Parses calibration YAML text (OpenCV or ROS), and says which of the two it was.
    ///
    /// # Errors
    /// YAML that does not parse, a missing or bad field (naming it), or a lens whose
    /// distortion folds over inside the image.
    pub fn from_yaml_str_with_format(
        text: &str,
    ) -> Result<(Self, CalibrationFormat), CalibrationError> {
        let text = text.trim_start_matches('\u{feff}');
        let opencv_header = text.starts_with("%YAML:");
        let raw: RawFile = serde_saphyr::from_str(text).map_err(|e| CalibrationError::Yaml {
            message: e.to_string(),
        })?;
        let width = size(raw.image_width, "image_width")?;
        let height = size(raw.image_height, "image_height")?;
        let cm = raw
            .camera_matrix
            .as_ref()
            .ok_or(CalibrationError::MissingField {
                field: "camera_matrix",
            })?;
        let k = matrix_data(
            cm,
            "camera_matrix",
            "camera_matrix.data",
            |r, c| r == 3 && c == 3,
            "must be 3x3",
        )?;
        let kmat = Matrix3::from_row_slice(k);
        let intrinsics =
            Intrinsics::from_matrix(&kmat).map_err(|e| CalibrationError::BadField {
                field: "camera_matrix",
                reason: e.to_string(),
            })?;

        let ros = raw.distortion_model.is_some();
        let distortion = distortion(&raw)?;
        let has_dt = cm.dt.is_some()
            || raw
                .distortion_coefficients
                .as_ref()
                .is_some_and(|d| d.dt.is_some());
        let format = if opencv_header || (has_dt && !ros) {
            CalibrationFormat::OpenCv
        } else {
            CalibrationFormat::Ros
        };
        check_lens(&intrinsics, &distortion, width, height)?;
        Ok((
            Self {
                intrinsics,
                distortion,
                width,
                height,
            },
            format,
        ))
    }
}

/// Focal lengths, in multiples of the image side, that a camera can have: below, the field
/// of view would exceed 179.9 degrees; above, it would be under 0.06 degrees.
const FOCAL_RANGE: std::ops::RangeInclusive<f64> = 1e-3..=1e3;

/// The largest factor by which a lens's radial distortion may scale the ray through the
/// image's farthest corner (distorted over undistorted radius, or angle for a fisheye), and
/// the inverse of the smallest.
const MAX_CORNER_SCALE: f64 = 2.5;

/// Whether the intrinsics and distortion can describe a real camera for a `width x
/// height` image: focal lengths in [`FOCAL_RANGE`] times the image side, the principal
/// point within one image size of the image, and a radial distortion that is monotonic
/// (so invertible) out to the image's farthest corner.
fn check_lens(
    k: &Intrinsics,
    d: &Distortion,
    width: u32,
    height: u32,
) -> Result<(), CalibrationError> {
    let (w, h) = (f64::from(width), f64::from(height));
    for (name, f, side) in [("fx", k.alpha(), w), ("fy", k.beta(), h)] {
        if !FOCAL_RANGE.contains(&(f / side)) {
            return Err(CalibrationError::BadField {
                field: "camera_matrix",
                reason: format!(
                    "{name} = {f:e} px is not a focal length for a {side}-pixel image side (expected {:e} to {:e} px)",
                    FOCAL_RANGE.start() * side,
                    FOCAL_RANGE.end() * side
                ),
            });
        }
    }
    for (name, c, side) in [("cx", k.u0(), w), ("cy", k.v0(), h)] {
        if !(-side..=2.0 * side).contains(&c) {
            return Err(CalibrationError::BadField {
                field: "camera_matrix",
                reason: format!(
                    "{name} = {c} px puts the principal point more than an image size outside the {width}x{height} image"
                ),
            });
        }
    }
    // The farthest image corner, in normalised (distorted) coordinates.
    let corner_radius = [
        (-0.5, -0.5),
        (w - 0.5, -0.5),
        (-0.5, h - 0.5),
        (w - 0.5, h - 0.5),
    ]
    .iter()
    .map(|&(u, v)| {
        let m = k.matrix();
        let y = (v - k.v0()) / m[(1, 1)];
        let x = (u - k.u0() - m[(0, 1)] * y) / m[(0, 0)];
        x.hypot(y)
    })
    .fold(0.0, f64::max);
    // March the undistorted radius (fisheye: the ray's angle) until its distorted image
    // passes the corner; the profile's slope must stay positive on the way.
    let (what, unit) = match d.model() {
        DistortionModel::Equidistant => ("angle", " rad off the axis"),
        _ => ("normalised radius", ""),
    };
    match d.check_monotonic(corner_radius) {
        // A lens bends the corner's ray by a modest factor (strong barrel distortion about
        // 0.6, pincushion about 1.3); k2 = 1e6 squeezed a 72-degree view into 7 degrees and
        // put a robot 2 m away at 14 m.
        Ok(reached) => {
            let scale = corner_radius / reached.max(f64::MIN_POSITIVE);
            if (1.0 / MAX_CORNER_SCALE..=MAX_CORNER_SCALE).contains(&scale) {
                Ok(())
            } else {
                Err(CalibrationError::BadField {
                    field: "distortion_coefficients",
                    reason: format!(
                        "the {} radial distortion scales the image corner's ray by {scale:.3e} (a lens: {:.2} to {MAX_CORNER_SCALE}); coefficients {:?} are not a lens for this camera matrix",
                        d.model(),
                        1.0 / MAX_CORNER_SCALE,
                        d.coefficients()
                    ),
                })
            }
        }
        Err(ProfileFault::FoldsBack(t)) => Err(CalibrationError::BadField {
            field: "distortion_coefficients",
            reason: format!(
                "the {} radial distortion folds back at {what} {t:.3}{unit}, inside the image (its corner is at normalised radius {corner_radius:.3}): not a lens",
                d.model()
            ),
        }),
        Err(ProfileFault::NeverReaches) => Err(CalibrationError::BadField {
            field: "distortion_coefficients",
            reason: format!(
                "the {} radial distortion never reaches the image corner (normalised radius {corner_radius:.3}): not a lens",
                d.model()
            ),
        }),
    }
}

/// The distortion of a file: the model named by `distortion_model` (ROS, and OpenCV files that
/// carry the key) or `fisheye_model: 1` (OpenCV's calibration sample), else the model that
/// OpenCV's coefficient count implies (4 or 5: `plumb_bob`, 8: `rational_polynomial`).
fn distortion(raw: &RawFile) -> Result<Distortion, CalibrationError> {
    let named = match &raw.distortion_model {
        Some(name) => {
            Some(
                DistortionModel::from_name(name).map_err(|e| CalibrationError::BadField {
                    field: "distortion_model",
                    reason: e.to_string(),
                })?,
            )
        }
        None => None,
    };
    let fisheye = raw.fisheye_model.is_some_and(|f| f != 0);
    let model = match (named, fisheye) {
        (Some(m), true) if m != DistortionModel::Equidistant => {
            return Err(CalibrationError::BadField {
                field: "distortion_model",
                reason: format!(
                    "`{m}` contradicts `fisheye_model: 1` (the fisheye model is equidistant)"
                ),
            });
        }
        (None, true) => Some(DistortionModel::Equidistant),
        (m, _) => m,
    };
    let data = match &raw.distortion_coefficients {
        None => &[][..],
        Some(d) => matrix_data(
            d,
            "distortion_coefficients",
            "distortion_coefficients.data",
            |r, c| r == 1 || c == 1,
            "must be a row or column vector",
        )?,
    };
    let bad = |e: PoseError| CalibrationError::BadField {
        field: "distortion_coefficients",
        reason: e.to_string(),
    };
    match model {
        Some(m) => Distortion::from_model(m, data).map_err(bad),
        None if data.is_empty() => Ok(Distortion::NONE),
        None => Distortion::from_opencv(data).map_err(bad),
    }
}

fn size(v: Option<i64>, field: &'static str) -> Result<u32, CalibrationError> {
    let v = v.ok_or(CalibrationError::MissingField { field })?;
    u32::try_from(v)
        .ok()
        .filter(|v| *v > 0)
        .ok_or(CalibrationError::BadField {
            field,
            reason: format!("{v} is not a positive image size"),
        })
}

fn matrix_data<'a>(
    m: &'a RawMatrix,
    field: &'static str,
    data_field: &'static str,
    shape_ok: impl Fn(usize, usize) -> bool,
    shape_msg: &str,
) -> Result<&'a [f64], CalibrationError> {
    let data = m
        .data
        .as_deref()
        .ok_or(CalibrationError::MissingField { field: data_field })?;
    if let Some(dt) = &m.dt
        && dt != "d"
        && dt != "f"
    {
        return Err(CalibrationError::BadField {
            field,
            reason: format!("element type `{dt}` is not d or f"),
        });
    }
    let rows = m
        .rows
        .unwrap_or(if shape_ok(1, data.len()) { 1 } else { 0 });
    let cols = m
        .cols
        .unwrap_or_else(|| data.len().checked_div(rows).unwrap_or(0));
    if !shape_ok(rows, cols) {
        return Err(CalibrationError::BadField {
            field,
            reason: format!("{rows}x{cols}: {shape_msg}"),
        });
    }
    if rows * cols != data.len() {
        return Err(CalibrationError::BadField {
            field,
            reason: format!(
                "{rows}x{cols} needs {} values, data has {}",
                rows * cols,
                data.len()
            ),
        });
    }
    if let Some(i) = data.iter().position(|v| !v.is_finite()) {
        return Err(CalibrationError::BadField {
            field,
            reason: format!(
                "data[{i}] (row {}, column {}) is {:?}, not a finite number",
                i / cols.max(1),
                i % cols.max(1),
                data[i]
            ),
        });
    }
    Ok(data)
}
