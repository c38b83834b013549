//! Scenes of leader robots seen from a follower's camera, rendered by `synthcam` with exact
//! ground truth: the bridge between our rig (faces, dictionary entries) and the synthetic
//! camera, which knows nothing about markers.
//!
//! A [`SceneSpec`] is plain data (a scene file, YAML or JSON): the leaders as unicycle poses
//! `(x, y, theta)` with their robot numbers, the camera robot's pose (default: the origin,
//! heading 0), the camera mount (spec 2.5), the image size and horizontal field of view,
//! and the render effects (supersampling, blur, seeded noise). [`build_scene`] turns it into a
//! `synthcam` scene: each leader gets a body and the rig's faces, each face a
//! [`synthcam::CellGrid`] texture of its marker (quiet zone, black border, data cells from
//! the dictionary code, bit `k = row * n + col`, black = 1), so cell edges are exact.
//! [`render_scene`] renders it and returns the image and a [`SceneTruth`]: per robot, its
//! pose in the camera frame, its true formation variables, and per face the marker's
//! corners (by exact projection), off-axis angle, width and whether it *should be read*
//! ([`FaceTruthOut::readable`]: visible, off-axis at most [`MAX_OFF_AXIS_DEG`], at least
//! [`MIN_WIDTH_PX`] wide).

use std::path::Path;
use std::sync::Arc;

use fiducial::{Dictionary, MarkerFamily};
use nalgebra::{Point2, Point3, Vector3};
use serde::{Deserialize, Serialize};
use thiserror::Error;

use formation_io::textfile;
use formation_tracker::mount::{self, CameraMount, MeasurementError};
use formation_tracker::rig::RigError;
use formation_tracker::rig::RigModel;
use nalgebra::{Isometry3, Translation3, UnitQuaternion};
use unicycle::{Formation, PlanarPose};

/// Faces seen more obliquely than this (degrees) are not required to be read.
pub const MAX_OFF_AXIS_DEG: f64 = 75.0;
/// Markers narrower than this in the image (pixels) are not required to be read.
pub const MIN_WIDTH_PX: f64 = 14.0;

/// What is wrong with a scene.
#[derive(Debug, Error)]
pub enum SceneError {
    /// A field of the file `path` is out of range ([`Self::Field`], from
    /// [`SceneSpec::load`], which knows the file).
    #[error("{path}: {source}")]
    InFile {
        /// The file.
        path: String,
        /// The field's error.
        source: Box<SceneError>,
    },
    /// The file could not be read.
    #[error("cannot read scene file {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// The file is not a valid scene (syntax, unknown or mistyped field).
    #[error("scene file {path}: {message}")]
    Parse {
        /// The file.
        path: String,
        /// The parser's message.
        message: String,
    },
    /// A field has a value that makes no scene.
    #[error("scene: field `{field}`: {reason}")]
    Field {
        /// The field, e.g. `robots[1].robot`.
        field: String,
        /// What is wrong with it.
        reason: String,
    },
    /// The rig is invalid or lacks a marker for a robot.
    #[error(transparent)]
    Rig(#[from] RigError),
    /// The camera's intrinsics are invalid.
    #[error(transparent)]
    Camera(#[from] pose::PoseError),
    /// The synthetic camera refused the scene.
    #[error(transparent)]
    Synth(#[from] synthcam::SynthError),
    /// A marker could not be built.
    #[error(transparent)]
    Fiducial(#[from] fiducial::FiducialError),
    /// The true formation variables are undefined (a leader on top of the camera).
    #[error(transparent)]
    Measurement(#[from] MeasurementError),
}

fn field(name: impl Into<String>, reason: impl Into<String>) -> SceneError {
    SceneError::Field {
        field: name.into(),
        reason: reason.into(),
    }
}

/// Image size and field of view of a pinhole camera (square pixels, centred principal point).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CameraSpec {
    /// Image width, pixels.
    pub width: usize,
    /// Image height, pixels.
    pub height: usize,
    /// Horizontal field of view, degrees.
    pub hfov_deg: f64,
}

impl Default for CameraSpec {
    /// 640 x 480, 60 degrees (the paper scenes).
    fn default() -> Self {
        Self {
            width: 640,
            height: 480,
            hfov_deg: 60.0,
        }
    }
}

/// Render effects.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RenderSpec {
    /// Samples per pixel side (8: 64 samples per pixel).
    pub supersampling: usize,
    /// Sensor noise standard deviation, grey levels.
    pub noise_sigma: f64,
    /// Optical blur standard deviation, pixels.
    pub blur_sigma: f64,
    /// Noise seed.
    pub seed: u64,
}

impl Default for RenderSpec {
    /// The paper scenes' effects: 8 x 8 samples per pixel, noise sigma 3, blur sigma 1,
    /// seed 0. The samples approximate a sensor's exact area integral: with `synthcam`'s
    /// pattern (every sample in its own column and row) an axis-aligned edge, such as the
    /// level camera's vertical marker edges, lands within `1 / (2 n^2)` px of its true place
    /// with `n x n` samples: 0.125 px at 2 x 2 (a bias the pose would inherit), 0.008 px at
    /// 8 x 8.
    fn default() -> Self {
        Self {
            supersampling: 8,
            noise_sigma: 3.0,
            blur_sigma: 1.0,
            seed: 0,
        }
    }
}

/// One leader in a scene.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RobotSpec {
    /// Robot number (from 1): selects its markers through the rig's table.
    pub robot: u32,
    /// x, metres.
    pub x: f64,
    /// y, metres.
    pub y: f64,
    /// Heading, radians.
    pub theta: f64,
}

impl RobotSpec {
    /// The leader's planar pose.
    pub fn pose(&self) -> PlanarPose {
        PlanarPose::new(self.x, self.y, self.theta)
    }
}

/// The camera mount of the paper scenes: level, at marker height (0.30 m), no offset, no pan.
pub fn paper_mount() -> CameraMount {
    CameraMount {
        offset: 0.0,
        height: 0.30,
        pan: 0.0,
        tilt: 0.0,
    }
}

/// A scene file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneSpec {
    /// A label for reports.
    #[serde(default)]
    pub name: String,
    /// The camera robot's pose (default: the origin, heading 0).
    #[serde(default)]
    pub camera_robot: PlanarPose,
    /// Camera mount on the camera robot (default: [`paper_mount`]).
    #[serde(default = "paper_mount")]
    pub mount: CameraMount,
    /// Image size and field of view.
    #[serde(default)]
    pub camera: CameraSpec,
    /// Render effects.
    #[serde(default)]
    pub render: RenderSpec,
    /// The leaders.
    pub robots: Vec<RobotSpec>,
}

impl SceneSpec {
    /// Parses a scene file's text (JSON when `json`, else YAML). `path` labels errors.
    pub fn from_text(text: &str, json: bool, path: &str) -> Result<Self, SceneError> {
        let spec: Self = textfile::parse(text, json).map_err(|message| SceneError::Parse {
            path: path.to_string(),
            message,
        })?;
        spec.validate()?;
        Ok(spec)
    }

    /// Reads a scene file (`.json` as JSON, anything else as YAML).
    pub fn load(path: &Path) -> Result<Self, SceneError> {
        let (text, json) = textfile::read(path).map_err(|source| SceneError::Io {
            path: path.display().to_string(),
            source,
        })?;
        let name = path.display().to_string();
        Self::from_text(&text, json, &name).map_err(|e| match e {
            SceneError::Field { .. } => SceneError::InFile {
                path: name,
                source: Box::new(e),
            },
            e => e,
        })
    }

    /// Checks the fields a renderer would otherwise reject with a less precise message, and
    /// the physics: a mount a robot can have, headings within +-pi, no robot on the camera.
    pub fn validate(&self) -> Result<(), SceneError> {
        let c = &self.camera;
        if c.width == 0 || c.height == 0 || c.width > 8192 || c.height > 8192 {
            return Err(field(
                "camera.width/height",
                format!(
                    "{} x {} is not an image size in 1..=8192",
                    c.width, c.height
                ),
            ));
        }
        if !(c.hfov_deg.is_finite() && c.hfov_deg > 1.0 && c.hfov_deg < 170.0) {
            return Err(field(
                "camera.hfov_deg",
                format!("must be in (1, 170) degrees, got {}", c.hfov_deg),
            ));
        }
        let r = &self.render;
        if !(1..=8).contains(&r.supersampling) {
            return Err(field(
                "render.supersampling",
                format!(
                    "must be 1..=8 samples per pixel side, got {}",
                    r.supersampling
                ),
            ));
        }
        for (name, v) in [
            ("render.noise_sigma", r.noise_sigma),
            ("render.blur_sigma", r.blur_sigma),
        ] {
            if !(v.is_finite() && (0.0..=50.0).contains(&v)) {
                return Err(field(name, format!("must be in [0, 50], got {v}")));
            }
        }
        let m = &self.mount;
        let (pi, half_pi) = (std::f64::consts::PI, std::f64::consts::FRAC_PI_2);
        for (name, v, ok, range) in [
            (
                "mount.offset",
                m.offset,
                (0.0..100.0).contains(&m.offset),
                "0 up to 100 m",
            ),
            (
                "mount.height",
                m.height,
                m.height > 0.0 && m.height < 100.0,
                "above 0 and below 100 m",
            ),
            ("mount.pan", m.pan, m.pan.abs() <= pi, "-pi to pi rad"),
            (
                "mount.tilt",
                m.tilt,
                m.tilt.abs() < half_pi,
                "inside -pi/2 to pi/2 rad",
            ),
        ] {
            if !ok {
                let hint = if name.ends_with("pan") || name.ends_with("tilt") {
                    degrees_hint(v)
                } else {
                    String::new()
                };
                return Err(field(name, format!("{v:?} is outside {range}{hint}")));
            }
        }
        let p = &self.camera_robot;
        for (name, v) in [
            ("camera_robot.x", p.x),
            ("camera_robot.y", p.y),
            ("camera_robot.theta", p.theta),
        ] {
            if !v.is_finite() || v.abs() > 1e4 {
                return Err(field(
                    name,
                    format!("must be finite and within 1e4, got {v}"),
                ));
            }
        }
        for (i, rb) in self.robots.iter().enumerate() {
            if rb.robot == 0 {
                return Err(field(
                    format!("robots[{i}].robot"),
                    "robot numbers start at 1",
                ));
            }
            if let Some(j) = self.robots[..i].iter().position(|o| o.robot == rb.robot) {
                return Err(field(
                    format!("robots[{i}].robot"),
                    format!("robot {} is already robots[{j}]", rb.robot),
                ));
            }
            for (name, v) in [("x", rb.x), ("y", rb.y), ("theta", rb.theta)] {
                if !v.is_finite() || v.abs() > 1e4 {
                    return Err(field(
                        format!("robots[{i}].{name}"),
                        format!("must be finite and within 1e4, got {v}"),
                    ));
                }
            }
            if rb.theta.abs() > std::f64::consts::PI {
                return Err(field(
                    format!("robots[{i}].theta"),
                    format!(
                        "{:?} rad is outside -pi to pi{}",
                        rb.theta,
                        degrees_hint(rb.theta)
                    ),
                ));
            }
            // A robot on the camera is no scene (it was rendered as nonsense with exit 0).
            let (hs, hc) = p.theta.sin_cos();
            let camera = (p.x + m.offset * hc, p.y + m.offset * hs);
            let apart = (rb.x - camera.0).hypot(rb.y - camera.1);
            if apart < MIN_CAMERA_DISTANCE {
                return Err(field(
                    format!("robots[{i}]"),
                    format!(
                        "({:?}, {:?}) is {apart:.3} m from the camera at ({:.3}, {:.3}); a robot stands at least {MIN_CAMERA_DISTANCE} m from it",
                        rb.x, rb.y, camera.0, camera.1
                    ),
                ));
            }
        }
        if p.theta.abs() > std::f64::consts::PI {
            return Err(field(
                "camera_robot.theta",
                format!(
                    "{:?} rad is outside -pi to pi{}",
                    p.theta,
                    degrees_hint(p.theta)
                ),
            ));
        }
        Ok(())
    }
}

/// A marker as a cell grid: a one-cell white quiet zone, a one-cell black border and the
/// data cells of `code` (bit `k = row * n + col`, black = 1, row 0 at the top).
pub fn marker_texture(family: MarkerFamily, code: u64) -> Result<synthcam::CellGrid, SceneError> {
    let code = family.check_code(code)?;
    let (m, n) = (family.rows() as usize, family.cols() as usize);
    let (rows, cols) = (m + 4, n + 4);
    let mut black = vec![false; rows * cols];
    for r in 1..rows - 1 {
        for c in 1..cols - 1 {
            let border = r == 1 || r == rows - 2 || c == 1 || c == cols - 2;
            black[r * cols + c] = border || family.bit(code, (r - 2) as u32, (c - 2) as u32);
        }
    }
    Ok(synthcam::CellGrid::from_bits(rows, cols, &black)?)
}

/// The rigid transform camera frame -> body frame of `mount`: the form `synthcam` takes.
pub fn camera_to_body(mount: &CameraMount) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::from(mount.camera_position()),
        UnitQuaternion::from_rotation_matrix(&mount.camera_to_body_rotation()),
    )
}

/// A built scene, ready to render.
#[derive(Debug, Clone)]
pub struct BuiltScene {
    /// The synthetic camera's scene.
    pub scene: synthcam::Scene,
    /// The camera.
    pub camera: synthcam::PosedCamera,
    /// Render settings.
    pub settings: synthcam::RenderSettings,
}

/// Builds the `synthcam` scene of `spec` with `rig`'s faces and markers from `dictionary`.
pub fn build_scene(
    spec: &SceneSpec,
    rig: &RigModel,
    dictionary: &Dictionary,
) -> Result<BuiltScene, SceneError> {
    spec.validate()?;
    let family = rig.geometry.family()?;
    let cell = rig.geometry.cell_size_m;
    let tex_w = f64::from(family.width_cells() + 2) * cell;
    let tex_h = f64::from(family.height_cells() + 2) * cell;
    let face_bottom = rig.geometry.marker_centre_height_m - tex_h / 2.0;
    let body = if face_bottom > 0.02 {
        synthcam::Body::Cylinder {
            radius: 0.8 * rig.geometry.apothem_m(),
            height: face_bottom - 0.01,
            albedo: 0.35,
        }
    } else {
        synthcam::Body::None
    };
    let mut scene = synthcam::Scene::new(0.8);
    scene.ground = Some(synthcam::Ground {
        texture: Arc::new(synthcam::SoftChecker::new(0.42, 0.58)?),
        tile: 1.0,
    });
    let geometries = rig.face_geometries()?;
    for rb in &spec.robots {
        let mut robot = synthcam::Robot::new(rb.pose(), body);
        for g in &geometries {
            let code = rig.code(dictionary, rb.robot, g.face)?;
            let texture = Arc::new(marker_texture(family, code)?);
            let placement = synthcam::FacePlacement {
                centre: Point3::from(g.centre),
                normal: Vector3::from(g.normal),
                up: Vector3::z(),
                width: tex_w,
                height: tex_h,
            };
            robot = robot.with_face(synthcam::Face::new(u32::from(g.face), placement, texture));
        }
        scene.robots.push(robot);
    }
    let (width, height) = (spec.camera.width, spec.camera.height);
    // `validate` bounds the size to 8192 px a side.
    let intrinsics = pose::Intrinsics::from_hfov(
        spec.camera.hfov_deg.to_radians(),
        width as u32,
        height as u32,
    )?;
    let camera = synthcam::PosedCamera::on_robot(
        intrinsics,
        width,
        height,
        &camera_to_body(&spec.mount),
        &spec.camera_robot,
    )?;
    let settings = synthcam::RenderSettings {
        supersampling: spec.render.supersampling,
        blur_sigma: spec.render.blur_sigma,
        noise_sigma: spec.render.noise_sigma,
        seed: spec.render.seed,
        shading: None,
        ..synthcam::RenderSettings::default()
    };
    Ok(BuiltScene {
        scene,
        camera,
        settings,
    })
}

/// Ground truth of one face of one robot.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FaceTruthOut {
    /// Face number.
    pub face: u8,
    /// Dictionary entry on this face.
    pub index: usize,
    /// Its code.
    pub code: u64,
    /// The face (marker and quiet zone) is front-facing, in the image and unoccluded.
    pub visible: bool,
    /// Angle between the face normal and the direction to the camera, radians (0: face-on).
    pub off_axis: f64,
    /// Mean projected width of the marker's black border (top and bottom edges), pixels.
    pub width_px: Option<f64>,
    /// The black border's outer corners NW, NE, SE, SW by exact projection (pixel centres
    /// at integers), when all are in front of the camera.
    pub corners_px: Option<[[f64; 2]; 4]>,
    /// Visible, off-axis at most 75 degrees and at least 14 px wide: must be read.
    pub readable: bool,
    /// Front-facing and inside the image, but some (not all) of the face's corners are
    /// hidden behind another object (another robot, the rig itself): the face is cut by an
    /// occluder, and whatever of it is read may have a side along the occluder's edge.
    #[serde(default)]
    pub partly_hidden: bool,
}

/// Ground truth of one robot.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RobotTruthOut {
    /// Robot number.
    pub robot: u32,
    /// World pose.
    pub pose: PlanarPose,
    /// Rotation vector, rig (body) frame -> camera frame.
    pub rotation: [f64; 3],
    /// Rig origin in the camera frame, metres.
    pub translation: [f64; 3],
    /// Heading of the leader relative to the camera robot, radians.
    pub relative_heading: f64,
    /// True formation: `l12` (m, from the camera point), `alpha12`, `beta12` (rad); flat
    /// in JSON.
    #[serde(flatten)]
    pub formation: Formation,
    /// Every face of the rig.
    pub faces: Vec<FaceTruthOut>,
}

/// Ground truth of a frame, as written by `render --truth`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SceneTruth {
    /// Scene name.
    pub name: String,
    /// Image width.
    pub width: usize,
    /// Image height.
    pub height: usize,
    /// Camera matrix `K` (rows).
    pub k: [[f64; 3]; 3],
    /// Camera mount.
    pub mount: CameraMount,
    /// The leaders.
    pub robots: Vec<RobotTruthOut>,
}

impl SceneTruth {
    /// The truth of robot `robot`.
    pub fn robot(&self, robot: u32) -> Option<&RobotTruthOut> {
        self.robots.iter().find(|r| r.robot == robot)
    }
}

/// Ground truth of `spec` without rendering.
pub fn scene_truth(
    spec: &SceneSpec,
    built: &BuiltScene,
    rig: &RigModel,
    dictionary: &Dictionary,
) -> Result<SceneTruth, SceneError> {
    let truth = synthcam::ground_truth(&built.scene, &built.camera)?;
    truth_from(spec, &truth, rig, dictionary)
}

fn truth_from(
    spec: &SceneSpec,
    truth: &synthcam::FrameTruth,
    rig: &RigModel,
    dictionary: &Dictionary,
) -> Result<SceneTruth, SceneError> {
    let intr = truth.camera;
    let geometries = rig.face_geometries()?;
    let mut robots = Vec::with_capacity(spec.robots.len());
    for (rb, rt) in spec.robots.iter().zip(&truth.robots) {
        let b2c = rt.body_to_camera;
        let rot = b2c.rotation.to_rotation_matrix();
        let t = b2c.translation.vector;
        let f = mount::formation_from_camera_pose(&rot, &t, &spec.mount)?;
        let mut faces = Vec::with_capacity(geometries.len());
        for (g, ft) in geometries.iter().zip(&rt.faces) {
            let projected: Vec<Point2<f64>> = g
                .corner_points()
                .iter()
                .filter_map(|p| intr.project(&(b2c * p)))
                .collect();
            let corners = <[Point2<f64>; 4]>::try_from(projected).ok();
            let width_px = corners.map(|c| ((c[1] - c[0]).norm() + (c[2] - c[3]).norm()) / 2.0);
            let readable = ft.visible
                && ft.off_axis_deg <= MAX_OFF_AXIS_DEG
                && width_px.is_some_and(|w| w >= MIN_WIDTH_PX);
            faces.push(FaceTruthOut {
                face: g.face,
                index: rig.index_of(rb.robot, g.face).unwrap_or(usize::MAX),
                code: rig.code(dictionary, rb.robot, g.face)?,
                visible: ft.visible,
                off_axis: ft.off_axis_deg.to_radians(),
                width_px,
                corners_px: corners.map(|c| c.map(|p| [p.x, p.y])),
                readable,
                partly_hidden: ft.front_facing
                    && ft.in_front
                    && ft.inside_image
                    && ft.unoccluded.iter().any(|&u| u)
                    && !ft.unoccluded.iter().all(|&u| u),
            });
        }
        let rv = rot.scaled_axis();
        robots.push(RobotTruthOut {
            robot: rb.robot,
            pose: rb.pose(),
            rotation: [rv.x, rv.y, rv.z],
            translation: [t.x, t.y, t.z],
            relative_heading: unicycle::wrap_angle(rb.theta - spec.camera_robot.theta),
            formation: Formation::from_vector(&f),
            faces,
        });
    }
    let k = intr.k();
    Ok(SceneTruth {
        name: spec.name.clone(),
        width: intr.width(),
        height: intr.height(),
        k: [
            [k[(0, 0)], k[(0, 1)], k[(0, 2)]],
            [k[(1, 0)], k[(1, 1)], k[(1, 2)]],
            [k[(2, 0)], k[(2, 1)], k[(2, 2)]],
        ],
        mount: spec.mount,
        robots,
    })
}

/// A rendered scene: the 8-bit grey image and its ground truth.
#[derive(Debug, Clone)]
pub struct RenderedScene {
    /// The image.
    pub image: image::GrayImage,
    /// What it shows.
    pub truth: SceneTruth,
}

/// Renders `spec` with `rig` and `dictionary`.
pub fn render_scene(
    spec: &SceneSpec,
    rig: &RigModel,
    dictionary: &Dictionary,
) -> Result<RenderedScene, SceneError> {
    render_scene_with_progress(spec, rig, dictionary, &|_, _| {})
}

/// As [`render_scene`], calling `progress(rows_done, rows)` as the renderer traces the rows
/// of the image (see [`synthcam::render_with_progress`]).
pub fn render_scene_with_progress(
    spec: &SceneSpec,
    rig: &RigModel,
    dictionary: &Dictionary,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<RenderedScene, SceneError> {
    let built = build_scene(spec, rig, dictionary)?;
    let out =
        synthcam::render_with_progress(&built.scene, &built.camera, &built.settings, progress)?;
    let truth = truth_from(spec, &out.truth, rig, dictionary)?;
    let (w, h) = (out.frame.width, out.frame.height);
    let image =
        image::GrayImage::from_raw(w as u32, h as u32, out.frame.data).ok_or_else(|| {
            field(
                "camera.width/height",
                "the rendered frame does not match its size",
            )
        })?;
    Ok(RenderedScene { image, truth })
}

/// Renders one frame exposed over several instants: `specs` are the scene at sub-frame times
/// spread evenly over the exposure, in time order (motion blur, see
/// [`synthcam::render_exposure`]), all with the same camera size and render effects (those
/// of the middle one are used); `gradient` lights the image unevenly. The truth is that of
/// the middle scene. One scene and no gradient give exactly [`render_scene`].
///
/// # Errors
/// As [`render_scene`]; [`SceneError::Field`] when `specs` is empty.
pub fn render_scene_exposure(
    specs: &[SceneSpec],
    gradient: Option<synthcam::Gradient>,
    rig: &RigModel,
    dictionary: &Dictionary,
) -> Result<RenderedScene, SceneError> {
    let Some(middle) = specs.get(specs.len() / 2) else {
        return Err(field("specs", "an exposure needs at least one scene"));
    };
    let built: Vec<BuiltScene> = specs
        .iter()
        .map(|s| build_scene(s, rig, dictionary))
        .collect::<Result<_, _>>()?;
    let views: Vec<(&synthcam::Scene, &synthcam::PosedCamera)> =
        built.iter().map(|b| (&b.scene, &b.camera)).collect();
    let mut settings = built[specs.len() / 2].settings;
    settings.gradient = gradient;
    let out = synthcam::render_exposure(&views, &settings)?;
    let truth = truth_from(middle, &out.truth, rig, dictionary)?;
    let (w, h) = (out.frame.width, out.frame.height);
    let image =
        image::GrayImage::from_raw(w as u32, h as u32, out.frame.data).ok_or_else(|| {
            field(
                "camera.width/height",
                "the rendered frame does not match its size",
            )
        })?;
    Ok(RenderedScene { image, truth })
}
/// The closest a robot may stand to the camera's optical centre in a scene, metres.
const MIN_CAMERA_DISTANCE: f64 = 0.3;

/// `; did you mean 30 degrees = 0.5236 rad?` for an angle that could be in degrees.
fn degrees_hint(v: f64) -> String {
    if v.abs() <= 360.0 && v.abs() > std::f64::consts::PI {
        format!("; did you mean {v} degrees = {:.4} rad?", v.to_radians())
    } else {
        String::new()
    }
}
