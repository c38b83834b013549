//! Scenario files for the dual-UKF experiment (`reproduce dukf --scenario FILE`,
//! `cargo xtask dukf-table --scenario FILE`): the robots' start, the leader's inputs as sums
//! of constants, sines and steps, the follower's set-point changes, the measurement noise,
//! the duration and the filter's initial state. YAML, or JSON when the file is named `.json`.
//! `fixtures/scenarios/reference.yaml` is the built-in reference scenario
//! ([`ScenarioConfig::reference`]); it reproduces it exactly.
//!
//! ```yaml
//! camera_offset: 0.5        # d, metres
//! frame_rate: 30            # Hz; dt = 1 / frame_rate
//! duration: 8.0             # seconds
//! follower: [0.0, 0.0, 0.0] # x, y, theta
//! leader: [1.5, 0.25, 0.0]
//! leader_inputs:
//!   v: [{constant: 0.8}, {sine: {amplitude: 0.2, omega: 0.5}}]
//!   w: [{sine: {amplitude: 0.2, omega: 0.4}}]
//! setpoints: [{at: 4.0, l12: 1.5}]          # optional; by default the start is held
//! noise_std: [0.07, 0.03, 0.03]
//! bias: [-0.0702, 0.0248, 0.0236]           # optional
//! filter_x0: [1.5, 0.25, 0, 1.047, 0.233, 0.232]   # optional; the paper's by default
//! actuation:                                # optional; exact by default
//!   scale: [0.95, 1.0]                      # executed = scale * commanded, per [v, w]
//!   noise_std: [0.03, 0.03]                 # + white noise, m/s and rad/s
//! odometry_noise_std: [0.01, 0.01]          # optional; what the filter is given, m/s, rad/s
//! control: estimate                         # optional: estimate (default), truth or open
//! vision:                                   # optional; only `demo --scenario` reads it
//!   camera: {width: 640, height: 480, hfov_deg: 60}
//!   mount: {height: 0.30, pan: 0.0, tilt: 0.0}      # metres, radians; offset = camera_offset
//!   render:
//!     supersampling: 4      # samples per pixel side, 1..=8
//!     noise_sigma: 3.0      # grey levels
//!     blur_sigma: 1.0       # optical blur, pixels
//!     motion_blur: {exposure_s: 0.02, subframes: 3}  # optional
//!     gradient: {from: 1.0, to: 0.333, angle_deg: 0}   # optional light factor across the image
//!   occlusions: [{from: 3.5, to: 4.5}]      # seconds; [] for none; at most one interval
//! ```
//!
//! The `vision` section ([`VisionSpec`]) drives the end-to-end demo (`demo --scenario FILE`,
//! [`crate::demo::DemoConfig::from_scenario`]): every field is optional and defaults to the
//! built-in demo's value, so a file without it gives exactly `demo`'s camera, rendering and
//! occlusion. `reproduce dukf` ignores it; `noise_std`, `bias` and `filter_x0` are the
//! dual-UKF experiment's and the demo ignores them (its measurements come from the images).
//! `actuation` and `odometry_noise_std` are the follower's: in `reproduce dukf` and the demo
//! it moves by the executed inputs and the filter is given its odometry, never the executed
//! inputs. The demo's trackers are also told `odometry_noise_std`, as a robot knows its own
//! odometry's noise (`FilterTuning::input_noise_std` of `formation-filter`).
//! `control` says what the follower's controller acts on in `reproduce dukf` and
//! `cargo xtask dukf-table` ([`Control`]): `estimate` (the default, as on a robot: the
//! filter's estimate after each measurement), `truth` (the paper's setting, Figs. 12-13) or
//! `open` (no feedback: the commands of the planned run replayed). The demo ignores it: its
//! followers steer on the truth unless `demo --closed-loop` puts them on their trackers'
//! estimates.

use std::path::{Path, PathBuf};

use formation_filter::{FilterConfig, FilterDesign};
use formation_io::textfile;
use serde::Deserialize;
use unicycle::{Actuation, Inputs, PlanarPose, PolarState, UnicycleError};

use crate::reproduce::{ReproduceError, Reproduction, run_closed_loop};
use crate::scenario::{
    Control, PAPER_BIAS, PAPER_X0, Scenario, ScenarioConfig, ScenarioError, SetpointChange,
    Simulation, simulate_scheduled,
};
use crate::scene::CameraSpec;

/// Errors of reading a scenario file.
#[derive(Debug, thiserror::Error)]
pub enum ScenarioFileError {
    /// A field of the file `path` has a value the simulation cannot use ([`Self::Field`],
    /// from [`ScenarioSpec::load`], which knows the file).
    #[error("{}: {source}", path.display())]
    InFile {
        /// The file.
        path: PathBuf,
        /// The field's error.
        source: Box<ScenarioFileError>,
    },
    /// The file could not be read.
    #[error("cannot read scenario file {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The file is not a valid scenario (the parser's message names the field and position).
    #[error("scenario file {path}: {message}")]
    Parse {
        /// The file.
        path: PathBuf,
        /// What is wrong, and where.
        message: String,
    },
    /// A field has a value the simulation cannot use.
    #[error("scenario file: field `{field}`: {reason}")]
    Field {
        /// The field.
        field: String,
        /// Why it is refused.
        reason: String,
    },
}

/// One term of a leader input: the input is the sum of its terms at every time.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Term {
    /// A constant.
    Constant(f64),
    /// `amplitude sin(omega t + phase)`.
    Sine {
        /// Amplitude.
        amplitude: f64,
        /// Angular frequency, rad/s.
        omega: f64,
        /// Phase, radians (0 by default).
        #[serde(default)]
        phase: f64,
    },
    /// `value` from `t >= at` on, 0 before.
    Step {
        /// Time of the step, seconds.
        at: f64,
        /// Value after the step.
        value: f64,
    },
}

impl Term {
    fn at(&self, t: f64) -> f64 {
        match *self {
            Self::Constant(c) => c,
            Self::Sine {
                amplitude,
                omega,
                phase,
            } => amplitude * (omega * t + phase).sin(),
            Self::Step { at, value } => {
                if t >= at {
                    value
                } else {
                    0.0
                }
            }
        }
    }

    fn values(&self) -> Vec<f64> {
        match *self {
            Self::Constant(c) => vec![c],
            Self::Sine {
                amplitude,
                omega,
                phase,
            } => vec![amplitude, omega, phase],
            Self::Step { at, value } => vec![at, value],
        }
    }
}

/// Largest magnitude of a leader input term's value (a constant, a sine's amplitude, a
/// step's value): m/s for `v`, rad/s for `w`. No ground robot moves at 100 m/s or turns at
/// 100 rad/s; the bound keeps every sum of terms finite.
pub const MAX_INPUT: f64 = 100.0;

/// Largest angular frequency of a sine term, rad/s.
pub const MAX_OMEGA: f64 = 1000.0;

/// Most simulation steps a scenario may take (`duration * frame_rate`): the run keeps a
/// record per step.
pub const MAX_STEPS: f64 = 1.0e6;

impl Term {
    /// Checks the magnitudes against [`MAX_INPUT`] and [`MAX_OMEGA`], naming the field.
    fn check_bounds(&self, name: &str) -> Result<(), ScenarioFileError> {
        let (value, omega) = match *self {
            Self::Constant(c) => (c, 0.0),
            Self::Sine {
                amplitude, omega, ..
            } => (amplitude, omega),
            Self::Step { value, .. } => (value, 0.0),
        };
        if value.abs() > MAX_INPUT {
            return Err(field(
                name,
                format!("{value} is beyond {MAX_INPUT} (m/s or rad/s)"),
            ));
        }
        if omega.abs() > MAX_OMEGA {
            return Err(field(
                name,
                format!("angular frequency {omega} is beyond {MAX_OMEGA} rad/s"),
            ));
        }
        Ok(())
    }
}

fn sum(terms: &[Term], t: f64) -> f64 {
    terms.iter().fold(0.0, |acc, term| acc + term.at(t))
}

/// The leader's inputs as sums of terms.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LeaderInputs {
    /// Terms of `v1`, m/s.
    pub v: Vec<Term>,
    /// Terms of `w1`, rad/s.
    pub w: Vec<Term>,
}

/// A change of the follower's set-points.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Setpoint {
    /// Time, seconds.
    pub at: f64,
    /// New desired `l12`, metres.
    #[serde(default)]
    pub l12: Option<f64>,
    /// New desired `alpha12`, radians.
    #[serde(default)]
    pub alpha12: Option<f64>,
}

/// The camera mount of the vision demo, less its offset (the file's `camera_offset`).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MountSpec {
    /// Height of the optical centre above the ground, metres (0.30, the markers' centres).
    pub height: f64,
    /// Pan, radians, left positive (0).
    pub pan: f64,
    /// Tilt of the optical axis below the horizontal, radians (0).
    pub tilt: f64,
}

impl Default for MountSpec {
    fn default() -> Self {
        let m = formation_tracker::mount::CameraMount::default();
        Self {
            height: m.height,
            pan: m.pan,
            tilt: m.tilt,
        }
    }
}

/// Motion blur: each frame integrates the scene over an exposure centred on the frame time.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MotionBlurSpec {
    /// Exposure time, seconds (> 0, at most the frame period).
    pub exposure_s: f64,
    /// Sub-frames rendered and averaged over the exposure (odd, 3 to 15; default 5).
    #[serde(default = "default_subframes")]
    pub subframes: usize,
}

fn default_subframes() -> usize {
    5
}

/// A linear lighting gradient across the image: the light factor goes from `from` on one
/// side to `to` on the other, along the image direction `angle_deg` (0: left to right, 90:
/// top to bottom). `from: 1, to: 0.333` is a 3:1 gradient.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GradientSpec {
    /// Light factor at the start side (0 to 4).
    pub from: f64,
    /// Light factor at the end side (0 to 4).
    pub to: f64,
    /// Direction across the image, degrees (0 by default).
    #[serde(default)]
    pub angle_deg: f64,
}

/// How the vision demo renders its frames.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct VisionRenderSpec {
    /// Samples per pixel side, 1..=8 (4).
    pub supersampling: usize,
    /// Sensor noise standard deviation, grey levels (3).
    pub noise_sigma: f64,
    /// Optical blur standard deviation, pixels (1).
    pub blur_sigma: f64,
    /// Motion blur (none by default).
    pub motion_blur: Option<MotionBlurSpec>,
    /// Lighting gradient (none by default: uniform light).
    pub gradient: Option<GradientSpec>,
}

impl Default for VisionRenderSpec {
    fn default() -> Self {
        Self {
            supersampling: 4,
            noise_sigma: 3.0,
            blur_sigma: 1.0,
            motion_blur: None,
            gradient: None,
        }
    }
}

/// An interval during which the leader is hidden from the follower's camera, seconds.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OcclusionSpec {
    /// Start, seconds (included).
    pub from: f64,
    /// End, seconds (excluded).
    pub to: f64,
}

fn default_occlusions() -> Vec<OcclusionSpec> {
    vec![OcclusionSpec { from: 3.5, to: 4.5 }]
}

/// The vision demo's section of a scenario file (see the module documentation). Every field
/// defaults to the built-in demo's.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct VisionSpec {
    /// Image size and horizontal field of view (640 x 480, 60 degrees).
    pub camera: CameraSpec,
    /// The camera mount (0.30 m high, level, no pan).
    pub mount: MountSpec,
    /// Rendering effects.
    pub render: VisionRenderSpec,
    /// Occlusions of the leader (3.5 s to 4.5 s); `[]` for none, at most one.
    #[serde(default = "default_occlusions")]
    pub occlusions: Vec<OcclusionSpec>,
}

impl Default for VisionSpec {
    fn default() -> Self {
        Self {
            camera: CameraSpec::default(),
            mount: MountSpec::default(),
            render: VisionRenderSpec::default(),
            occlusions: default_occlusions(),
        }
    }
}

impl VisionSpec {
    /// Checks every field, naming it (`vision.render.noise_sigma`, ...) in the error.
    ///
    /// # Errors
    /// [`ScenarioFileError::Field`].
    pub fn check(&self, frame_period: f64) -> Result<(), ScenarioFileError> {
        let c = &self.camera;
        if !(16..=4096).contains(&c.width) || !(16..=4096).contains(&c.height) {
            return Err(field(
                "vision.camera",
                format!(
                    "{} x {} pixels: width and height must be from 16 to 4096",
                    c.width, c.height
                ),
            ));
        }
        if !(c.hfov_deg.is_finite() && c.hfov_deg > 1.0 && c.hfov_deg < 170.0) {
            return Err(field(
                "vision.camera.hfov_deg",
                format!("{} degrees: must be in (1, 170)", c.hfov_deg),
            ));
        }
        let m = &self.mount;
        if !(m.height.is_finite() && (0.0..=10.0).contains(&m.height)) {
            return Err(field(
                "vision.mount.height",
                format!("{} m: must be from 0 to 10 m", m.height),
            ));
        }
        for (name, v) in [("vision.mount.pan", m.pan), ("vision.mount.tilt", m.tilt)] {
            if !(v.is_finite() && v.abs() <= std::f64::consts::FRAC_PI_2) {
                return Err(field(
                    name,
                    format!("{v} rad: must be within +-pi/2 (radians, not degrees)"),
                ));
            }
        }
        let r = &self.render;
        if !(1..=8).contains(&r.supersampling) {
            return Err(field(
                "vision.render.supersampling",
                format!("{}: must be 1 to 8 samples per pixel side", r.supersampling),
            ));
        }
        for (name, v) in [
            ("vision.render.noise_sigma", r.noise_sigma),
            ("vision.render.blur_sigma", r.blur_sigma),
        ] {
            if !(v.is_finite() && (0.0..=50.0).contains(&v)) {
                return Err(field(name, format!("{v}: must be from 0 to 50")));
            }
        }
        if let Some(mb) = &r.motion_blur {
            if !(mb.exposure_s.is_finite()
                && mb.exposure_s > 0.0
                && mb.exposure_s <= frame_period + 1e-12)
            {
                return Err(field(
                    "vision.render.motion_blur.exposure_s",
                    format!(
                        "{} s: must be > 0 and at most the frame period {frame_period} s",
                        mb.exposure_s
                    ),
                ));
            }
            if !((3..=15).contains(&mb.subframes) && mb.subframes % 2 == 1) {
                return Err(field(
                    "vision.render.motion_blur.subframes",
                    format!(
                        "{}: must be odd, from 3 to 15 (the middle one is at the frame time)",
                        mb.subframes
                    ),
                ));
            }
        }
        if let Some(g) = &r.gradient {
            for (name, v) in [
                ("vision.render.gradient.from", g.from),
                ("vision.render.gradient.to", g.to),
            ] {
                if !(v.is_finite() && (0.0..=4.0).contains(&v)) {
                    return Err(field(name, format!("{v}: a light factor from 0 to 4")));
                }
            }
            if !g.angle_deg.is_finite() {
                return Err(field("vision.render.gradient.angle_deg", "must be finite"));
            }
        }
        if self.occlusions.len() > 1 {
            return Err(field(
                "vision.occlusions",
                format!(
                    "{} intervals given; the demo supports at most one",
                    self.occlusions.len()
                ),
            ));
        }
        for (i, o) in self.occlusions.iter().enumerate() {
            if !(o.from.is_finite() && o.to.is_finite() && o.from >= 0.0 && o.to > o.from) {
                return Err(field(
                    &format!("vision.occlusions[{i}]"),
                    format!(
                        "from {} s to {} s: must be finite with 0 <= from < to",
                        o.from, o.to
                    ),
                ));
            }
        }
        Ok(())
    }
}

/// A scenario file (see the module documentation).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScenarioSpec {
    /// Camera offset `d` of the follower, metres.
    pub camera_offset: f64,
    /// Frame rate, Hz (`dt = 1 / frame_rate`).
    pub frame_rate: f64,
    /// Duration, seconds.
    pub duration: f64,
    /// Follower's initial pose `[x, y, theta]`.
    pub follower: [f64; 3],
    /// Leader's initial pose `[x, y, theta]`.
    pub leader: [f64; 3],
    /// The leader's inputs.
    pub leader_inputs: LeaderInputs,
    /// The follower's set-point changes (none: it holds the initial formation).
    #[serde(default)]
    pub setpoints: Vec<Setpoint>,
    /// Measurement noise standard deviations `[l12, alpha12, beta12]`.
    pub noise_std: [f64; 3],
    /// Constant measurement bias, if any.
    #[serde(default)]
    pub bias: Option<[f64; 3]>,
    /// The filter's initial state `[x1, y1, theta1, l12, alpha12, beta12]` (the paper's by
    /// default).
    #[serde(default)]
    pub filter_x0: Option<[f64; 6]>,
    /// How the follower executes its commands: a scale per input and white noise on the
    /// executed inputs (exact by default, the paper's setting).
    #[serde(default)]
    pub actuation: Actuation,
    /// Standard deviations of the follower's odometry noise `[v, w]`, m/s and rad/s (none by
    /// default): the filter is given the executed inputs plus this noise.
    #[serde(default)]
    pub odometry_noise_std: [f64; 2],
    /// What the follower's controller acts on: `estimate` (default), `truth` (the paper's
    /// setting) or `open`.
    #[serde(default)]
    pub control: Control,
    /// The vision demo's camera, rendering and occlusions (`demo --scenario`); the built-in
    /// demo's by default.
    #[serde(default)]
    pub vision: VisionSpec,
}

fn field(field: &str, reason: impl Into<String>) -> ScenarioFileError {
    ScenarioFileError::Field {
        field: field.into(),
        reason: reason.into(),
    }
}

/// The largest distance, offset or separation in a scenario, metres.
const MAX_METRES: f64 = 100.0;

/// The largest coordinate of a pose, metres (10 km from the origin).
const MAX_POSITION: f64 = 1e4;

/// The smallest separation between the leader and the follower's camera, metres: the
/// robots' own size.
const MIN_SEPARATION: f64 = 0.3;

/// A position within [`MAX_POSITION`] of the origin.
fn position(name: &str, x: f64, y: f64) -> Result<(), ScenarioFileError> {
    if x.abs() <= MAX_POSITION && y.abs() <= MAX_POSITION {
        Ok(())
    } else {
        Err(field(
            name,
            format!("({x:?}, {y:?}) m: coordinates are within {MAX_POSITION} m of the origin"),
        ))
    }
}

/// An angle in radians within +-pi; a value that could be degrees says so.
fn angle(name: &str, v: f64) -> Result<(), ScenarioFileError> {
    if v.abs() <= std::f64::consts::PI {
        return Ok(());
    }
    let hint = if v.abs() <= 360.0 {
        format!("; did you mean {v} degrees = {:.4} rad?", v.to_radians())
    } else {
        String::new()
    };
    Err(field(name, format!("{v:?} rad is outside -pi to pi{hint}")))
}

/// `[l12, alpha12, beta12]`-shaped values (noise deviations, biases): metres up to
/// [`MAX_METRES`] / 10, radians up to pi.
fn measurement_scale(name: &str, v: &[f64; 3]) -> Result<(), ScenarioFileError> {
    let bounds = [
        MAX_METRES / 10.0,
        std::f64::consts::PI,
        std::f64::consts::PI,
    ];
    for (i, (x, b)) in v.iter().zip(bounds).enumerate() {
        if *x > b {
            return Err(field(
                &format!("{name}[{i}]"),
                format!(
                    "{x:?}: at most {b:.4} ({})",
                    if i == 0 { "m" } else { "rad" }
                ),
            ));
        }
    }
    Ok(())
}

fn finite(name: &str, values: &[f64]) -> Result<(), ScenarioFileError> {
    if values.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        let (i, v) = values
            .iter()
            .enumerate()
            .find(|(_, v)| !v.is_finite())
            .map_or((0, f64::NAN), |(i, v)| (i, *v));
        Err(field(
            &format!("{name}[{i}]"),
            format!("{v:?}: every value must be finite"),
        ))
    }
}

impl ScenarioSpec {
    /// Parses a scenario from text (JSON when `json`, else YAML) and checks its values.
    ///
    /// # Errors
    /// [`ScenarioFileError::Parse`] (with `path` as given) or [`ScenarioFileError::Field`].
    pub fn parse(text: &str, json: bool, path: &Path) -> Result<Self, ScenarioFileError> {
        let spec: Self =
            textfile::parse(text, json).map_err(|message| ScenarioFileError::Parse {
                path: path.to_path_buf(),
                message,
            })?;
        spec.check()?;
        Ok(spec)
    }

    /// Reads and checks a scenario file.
    ///
    /// # Errors
    /// As [`ScenarioSpec::parse`], or the file cannot be read.
    pub fn load(path: &Path) -> Result<Self, ScenarioFileError> {
        let (text, json) = textfile::read(path).map_err(|source| ScenarioFileError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::parse(&text, json, path).map_err(|e| match e {
            ScenarioFileError::Field { .. } => ScenarioFileError::InFile {
                path: path.to_path_buf(),
                source: Box::new(e),
            },
            e => e,
        })
    }

    fn check(&self) -> Result<(), ScenarioFileError> {
        if !(self.camera_offset.is_finite() && self.camera_offset > 0.0) {
            return Err(field("camera_offset", "must be finite and > 0"));
        }
        if !(self.frame_rate.is_finite() && (0.001..=10_000.0).contains(&self.frame_rate)) {
            return Err(field(
                "frame_rate",
                "must be from 0.001 to 10000 frames per second",
            ));
        }
        if !(self.duration.is_finite() && self.duration > 0.0) {
            return Err(field("duration", "must be finite and > 0"));
        }
        if self.duration * self.frame_rate > MAX_STEPS {
            return Err(field(
                "duration",
                format!(
                    "{} s at {} frames/s is more than {MAX_STEPS} steps",
                    self.duration, self.frame_rate
                ),
            ));
        }
        if self.camera_offset > MAX_METRES {
            return Err(field(
                "camera_offset",
                format!(
                    "{:?} m: a camera offset is below {MAX_METRES} m",
                    self.camera_offset
                ),
            ));
        }
        for (name, pose) in [("follower", &self.follower), ("leader", &self.leader)] {
            finite(name, pose)?;
            position(name, pose[0], pose[1])?;
            angle(&format!("{name}[2]"), pose[2])?;
        }
        // The leader must stand ahead of the follower's camera, apart from it: a leader
        // placed on the follower gave exit 0 with nonsense.
        let [fx, fy, ft] = self.follower;
        let (cx, cy) = (
            fx + self.camera_offset * ft.cos(),
            fy + self.camera_offset * ft.sin(),
        );
        let separation = (self.leader[0] - cx).hypot(self.leader[1] - cy);
        if !(MIN_SEPARATION..=MAX_METRES).contains(&separation) {
            return Err(field(
                "leader",
                format!(
                    "({:?}, {:?}) is {separation:.3} m from the follower's camera at ({cx:.3}, {cy:.3}); robots stand {MIN_SEPARATION} to {MAX_METRES} m apart",
                    self.leader[0], self.leader[1]
                ),
            ));
        }
        finite("noise_std", &self.noise_std)?;
        if self.noise_std.iter().any(|&s| s <= 0.0) {
            return Err(field("noise_std", "every deviation must be > 0"));
        }
        measurement_scale("noise_std", &self.noise_std)?;
        for (name, terms) in [
            ("leader_inputs.v", &self.leader_inputs.v),
            ("leader_inputs.w", &self.leader_inputs.w),
        ] {
            for term in terms {
                finite(name, &term.values())?;
                term.check_bounds(name)?;
            }
        }
        for (i, s) in self.setpoints.iter().enumerate() {
            let name = format!("setpoints[{i}]");
            finite(
                &name,
                &[s.at, s.l12.unwrap_or(1.0), s.alpha12.unwrap_or(0.0)],
            )?;
            if let Some(l) = s.l12
                && !(MIN_SEPARATION..=MAX_METRES).contains(&l)
            {
                return Err(field(
                    &format!("{name}.l12"),
                    format!("{l:?} m: a separation is {MIN_SEPARATION} to {MAX_METRES} m"),
                ));
            }
            if let Some(a) = s.alpha12 {
                angle(&format!("{name}.alpha12"), a)?;
            }
            if !(0.0..=self.duration).contains(&s.at) {
                return Err(field(
                    &format!("{name}.at"),
                    format!(
                        "{:?} s: must lie within the run, 0 to {} s",
                        s.at, self.duration
                    ),
                ));
            }
        }
        if let Some(b) = &self.bias {
            finite("bias", b)?;
            measurement_scale("bias", &b.map(f64::abs))?;
        }
        if let Some(x0) = &self.filter_x0 {
            finite("filter_x0", x0)?;
            position("filter_x0", x0[0], x0[1])?;
            angle("filter_x0[2]", x0[2])?;
            if !(MIN_SEPARATION..=MAX_METRES).contains(&x0[3]) {
                return Err(field(
                    "filter_x0[3]",
                    format!(
                        "l12 = {:?} m: a separation is {MIN_SEPARATION} to {MAX_METRES} m",
                        x0[3]
                    ),
                ));
            }
            angle("filter_x0[4]", x0[4])?;
            angle("filter_x0[5]", x0[5])?;
        }
        self.actuation.validate().map_err(|e| match e {
            UnicycleError::InvalidActuation { name, .. } => {
                field(&format!("actuation.{name}"), e.to_string())
            }
            e => field("actuation", e.to_string()),
        })?;
        for (i, v) in self.odometry_noise_std.iter().enumerate() {
            if !(v.is_finite() && (0.0..=MAX_INPUT).contains(v)) {
                return Err(field(
                    &format!("odometry_noise_std[{i}]"),
                    format!("{v:?}: a standard deviation from 0 to {MAX_INPUT} (m/s or rad/s)"),
                ));
            }
        }
        self.vision.check(1.0 / self.frame_rate)?;
        Ok(())
    }

    /// The simulation configuration with `seed`; the bias is the file's, or the paper's when
    /// `paper_bias` and the file gives none.
    pub fn config(&self, seed: u64, paper_bias: bool) -> ScenarioConfig {
        let [fx, fy, ft] = self.follower;
        let [lx, ly, lt] = self.leader;
        ScenarioConfig {
            d: self.camera_offset,
            dt: 1.0 / self.frame_rate,
            duration: self.duration,
            follower0: PlanarPose::new(fx, fy, ft),
            leader0: PlanarPose::new(lx, ly, lt),
            noise_std: self.noise_std,
            bias: self.bias.or(paper_bias.then_some(PAPER_BIAS)),
            seed,
            actuation: self.actuation,
            odometry_noise_std: self.odometry_noise_std,
            control: self.control,
        }
    }

    /// The leader's inputs at time `t`.
    pub fn leader_inputs(&self, t: f64) -> Inputs {
        Inputs::new(sum(&self.leader_inputs.v, t), sum(&self.leader_inputs.w, t))
    }

    /// Simulates the scenario with `seed`.
    ///
    /// # Errors
    /// As [`simulate_scheduled`].
    pub fn simulate(&self, seed: u64, paper_bias: bool) -> Result<Scenario, ScenarioError> {
        simulate_scheduled(
            &self.config(seed, paper_bias),
            |t| self.leader_inputs(t),
            &self.setpoint_changes(),
        )
    }

    /// As [`Self::simulate`], one sample at a time in constant memory (the same samples).
    ///
    /// # Errors
    /// As [`Simulation::new`].
    pub fn simulation(
        &self,
        seed: u64,
        paper_bias: bool,
    ) -> Result<Simulation<impl Fn(f64) -> Inputs + '_>, ScenarioError> {
        Simulation::new(
            &self.config(seed, paper_bias),
            |t| self.leader_inputs(t),
            &self.setpoint_changes(),
        )
    }

    /// The set-point changes in the simulator's form.
    fn setpoint_changes(&self) -> Vec<SetpointChange> {
        self.setpoints
            .iter()
            .map(|s| SetpointChange {
                at: s.at,
                l12: s.l12,
                alpha12: s.alpha12,
            })
            .collect()
    }

    /// The filter's initial state: `filter_x0`, or the paper's.
    pub fn filter_x0(&self) -> [f64; 6] {
        self.filter_x0.unwrap_or(PAPER_X0)
    }

    /// The filter configuration: [`Self::filter_x0`] with the reference tuning and the
    /// IMM design (the design `reproduce dukf` runs, and the tracker's default too:
    /// `formation_tracker::tracker::TrackerConfig::reference`), told the follower's
    /// `odometry_noise_std` (`FilterTuning::input_noise_std`), as the demo's trackers are.
    pub fn filter_config(&self) -> FilterConfig {
        let mut config = FilterConfig::new(
            self.camera_offset,
            1.0 / self.frame_rate,
            PolarState::from_row_slice(&self.filter_x0()),
        );
        config.tuning.design = FilterDesign::Imm;
        config.tuning.input_noise_std = nalgebra::Vector2::from(self.odometry_noise_std);
        config
    }

    /// Simulates and filters the scenario with `seed` ([`Self::run`] with
    /// [`Self::filter_config`], told the follower's controller).
    ///
    /// # Errors
    /// Any [`ReproduceError`].
    pub fn reproduce(&self, seed: u64, paper_bias: bool) -> Result<Reproduction, ReproduceError> {
        Ok(self.run(seed, paper_bias, &self.filter_config(), true)?.1)
    }

    /// Simulates the scenario with `seed` with the filter `filter` in the loop
    /// ([`run_closed_loop`]): the samples (what the follower did under its `control`) and
    /// their filtered reproduction. With `control: truth` or `open` the samples are those of
    /// [`Self::simulate`].
    ///
    /// # Errors
    /// Any [`ReproduceError`].
    pub fn run(
        &self,
        seed: u64,
        paper_bias: bool,
        filter: &FilterConfig,
        follower_controller: bool,
    ) -> Result<(Scenario, Reproduction), ReproduceError> {
        run_closed_loop(
            self.simulation(seed, paper_bias)?,
            filter,
            follower_controller,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MINIMAL: &str = "camera_offset: 0.5\nframe_rate: 30\nduration: 1.0\n\
        follower: [0, 0, 0]\nleader: [1.5, 0.25, 0]\n\
        leader_inputs: {v: [{constant: 0.8}], w: [{step: {at: 0.5, value: 0.1}}]}\n\
        noise_std: [0.07, 0.03, 0.03]\n";

    /// A follower not told its controller still tells its filter when it changes its own
    /// set-point, as the demo's tracker is told (`FilterRun` since 2026-12-07): the IMM's
    /// model B, the formation held, gives its probability up at the change instead of
    /// predicting the leader moving with the follower.
    #[test]
    fn a_setpoint_change_is_told_to_a_filter_not_told_the_controller() {
        let text = MINIMAL
            .replace("duration: 1.0", "duration: 3.0")
            .replace("{step: {at: 0.5, value: 0.1}}", "{constant: 0.0}")
            + "setpoints: [{at: 2.0, l12: 1.8}]\ncontrol: truth\n";
        let spec = ScenarioSpec::parse(&text, false, Path::new("x.yaml")).unwrap();
        for seed in 1..=3 {
            let scenario = spec.simulate(seed, false).unwrap();
            let s = &scenario.samples;
            // The first sample with the new set-point; the step after it is filtered over it.
            let change = s
                .iter()
                .position(|x| x.controller.l12_desired != s[0].controller.l12_desired)
                .expect("the set-point changes");
            let config = spec.config(seed, false);
            let mut run =
                crate::reproduce::FilterRun::new(&spec.filter_config(), &config, false, false)
                    .unwrap();
            let mut b = Vec::with_capacity(s.len());
            for sample in s {
                run.push(sample).unwrap();
                b.push(run.filter().model_probabilities().expect("the IMM")[1]);
            }
            let (before, after) = (b[change], b[change + 1]);
            assert!(before > 0.5, "seed {seed}: B held {before} before");
            assert!(
                after < 0.2,
                "seed {seed}: B {after} after the change (was {before})"
            );
        }
    }

    #[test]
    fn terms_sum_and_steps_start_at_their_time() {
        let spec = ScenarioSpec::parse(MINIMAL, false, Path::new("x.yaml")).unwrap();
        assert_eq!(spec.leader_inputs(0.4), Inputs::new(0.8, 0.0));
        assert_eq!(spec.leader_inputs(0.5), Inputs::new(0.8, 0.1));
        assert_eq!(spec.filter_x0(), PAPER_X0);
        assert_eq!(spec.config(3, false).steps(), 30);
    }

    #[test]
    fn parse_errors_name_the_field() {
        let typo = MINIMAL.replace("frame_rate", "frame_rat");
        let err = ScenarioSpec::parse(&typo, false, Path::new("x.yaml"))
            .unwrap_err()
            .to_string();
        assert!(err.contains("frame_rat"), "{err}");
        let bad = MINIMAL.replace("duration: 1.0", "duration: -1.0");
        let err = ScenarioSpec::parse(&bad, false, Path::new("x.yaml"))
            .unwrap_err()
            .to_string();
        assert!(err.contains("`duration`"), "{err}");
        let bad = MINIMAL.replace("constant: 0.8", "cosine: 0.8");
        let err = ScenarioSpec::parse(&bad, false, Path::new("x.yaml"))
            .unwrap_err()
            .to_string();
        assert!(err.contains("cosine"), "{err}");
    }

    /// Found by the parser fuzz test: terms of 1e308 passed the finiteness check, and their
    /// sum (or `omega t`) made the leader's inputs infinite or NaN; a duration of 1e308 s
    /// would have simulated without end.
    #[test]
    fn inputs_and_durations_no_robot_has_are_refused() {
        for (from, to, what) in [
            ("constant: 0.8", "constant: 1e308", "leader_inputs.v"),
            (
                "{step: {at: 0.5, value: 0.1}}",
                "{sine: {amplitude: 1, omega: 1e300}}",
                "angular frequency",
            ),
            ("value: 0.1", "value: -101", "beyond 100"),
            ("duration: 1.0", "duration: 1e308", "steps"),
            (
                "frame_rate: 30",
                "frame_rate: 1e9",
                "10000 frames per second",
            ),
        ] {
            let bad = MINIMAL.replace(from, to);
            let err = ScenarioSpec::parse(&bad, false, Path::new("x.yaml"))
                .unwrap_err()
                .to_string();
            assert!(err.contains(what), "{to}: {err}");
        }
    }

    /// #32: a value of 1e308 reached the filter ("IMM model 0 ... overflowed", the field not
    /// named), and a leader placed on the follower gave exit 0 with nonsense. Every numeric
    /// field class is now bounded at parse time, and the message names the field.
    #[test]
    fn values_no_scenario_has_are_refused_naming_the_field() {
        let with_x0 = format!(
            "{MINIMAL}filter_x0: [1.5, 0.25, 0.0, 1.047, 0.233, 0.232]\nbias: [0, 0, 0]\nsetpoints: [{{at: 0.5, l12: 1.2}}]\n"
        );
        ScenarioSpec::parse(&with_x0, false, Path::new("x.yaml")).unwrap();
        for (from, to, what) in [
            (
                "camera_offset: 0.5",
                "camera_offset: 1e308",
                "`camera_offset`",
            ),
            (
                "follower: [0, 0, 0]",
                "follower: [1e308, 0, 0]",
                "`follower`",
            ),
            (
                "follower: [0, 0, 0]",
                "follower: [0, 0, 30]",
                "did you mean 30 degrees",
            ),
            (
                "leader: [1.5, 0.25, 0]",
                "leader: [0.5, 0.0, 0]",
                "0.000 m from the follower's camera",
            ),
            ("leader: [1.5, 0.25, 0]", "leader: [1e5, 0, 0]", "`leader`"),
            (
                "noise_std: [0.07, 0.03, 0.03]",
                "noise_std: [1e308, 0.03, 0.03]",
                "`noise_std[0]`",
            ),
            (
                "noise_std: [0.07, 0.03, 0.03]",
                "noise_std: [0.07, 7, 0.03]",
                "`noise_std[1]`",
            ),
            ("bias: [0, 0, 0]", "bias: [0, 0, 1e308]", "`bias[2]`"),
            ("bias: [0, 0, 0]", "bias: [0, .nan, 0]", "`bias[1]`"),
            (
                "1.047, 0.233, 0.232]",
                "1e308, 0.233, 0.232]",
                "`filter_x0[3]`",
            ),
            ("0.0, 1.047", "1e308, 1.047", "`filter_x0[2]`"),
            ("l12: 1.2", "l12: 1e308", "`setpoints[0].l12`"),
            ("at: 0.5", "at: 1e308", "`setpoints[0].at`"),
        ] {
            let bad = with_x0.replace(from, to);
            assert_ne!(bad, with_x0, "{from}");
            let err = ScenarioSpec::parse(&bad, false, Path::new("x.yaml"))
                .unwrap_err()
                .to_string();
            assert!(err.contains(what), "{to}: {err}");
        }
    }

    /// The follower's actuation and odometry (#30): read, checked with the field named, and
    /// handed to the simulation.
    #[test]
    fn actuation_and_odometry_are_read_and_bad_values_named() {
        let spec = ScenarioSpec::parse(MINIMAL, false, Path::new("x.yaml")).unwrap();
        assert!(spec.actuation.is_perfect());
        assert_eq!(spec.odometry_noise_std, [0.0; 2]);
        let with = format!(
            "{MINIMAL}actuation: {{scale: [0.95, 1.0], noise_std: [0.03, 0.02]}}
odometry_noise_std: [0.01, 0.005]
"
        );
        let spec = ScenarioSpec::parse(&with, false, Path::new("x.yaml")).unwrap();
        let config = spec.config(1, false);
        assert_eq!(config.actuation.scale, [0.95, 1.0]);
        assert_eq!(config.actuation.noise_std, [0.03, 0.02]);
        assert_eq!(config.odometry_noise_std, [0.01, 0.005]);
        // One part given: the other keeps its default.
        let partial = format!(
            "{MINIMAL}actuation: {{scale: [0.9, 1.0]}}
"
        );
        let spec = ScenarioSpec::parse(&partial, false, Path::new("x.yaml")).unwrap();
        assert_eq!(spec.actuation.noise_std, [0.0; 2]);
        for (from, to, what) in [
            (
                "scale: [0.95, 1.0]",
                "scale: [0.0, 1.0]",
                "`actuation.scale[0]`",
            ),
            (
                "scale: [0.95, 1.0]",
                "scale: [0.95, 3.0]",
                "`actuation.scale[1]`",
            ),
            (
                "noise_std: [0.03, 0.02]",
                "noise_std: [-0.1, 0.02]",
                "`actuation.noise_std[0]`",
            ),
            (
                "noise_std: [0.03, 0.02]",
                "noise_std: [0.03, .nan]",
                "`actuation`",
            ),
            (
                "odometry_noise_std: [0.01, 0.005]",
                "odometry_noise_std: [0.01, -1]",
                "`odometry_noise_std[1]`",
            ),
            (
                "odometry_noise_std: [0.01, 0.005]",
                "odometry_noise_std: [.inf, 0]",
                "`odometry_noise_std[0]`",
            ),
            ("{scale:", "{slip: 0.1, scale:", "slip"),
        ] {
            let bad = with.replace(from, to);
            assert_ne!(bad, with, "{from}");
            let err = ScenarioSpec::parse(&bad, false, Path::new("x.yaml"))
                .unwrap_err()
                .to_string();
            assert!(err.contains(what), "{to}: {err}");
        }
    }

    /// A field error of a file names the file (#32: it named only the field).
    #[test]
    fn field_errors_of_a_file_name_the_file() {
        let path = std::env::temp_dir().join(format!("ft-scenario-{}.yaml", std::process::id()));
        std::fs::write(
            &path,
            MINIMAL.replace("leader: [1.5, 0.25, 0]", "leader: [0.5, 0, 0]"),
        )
        .unwrap();
        let err = ScenarioSpec::load(&path).unwrap_err();
        let _ = std::fs::remove_file(&path);
        assert!(
            matches!(&err, ScenarioFileError::InFile { source, .. }
                if matches!(**source, ScenarioFileError::Field { .. })),
            "{err:?}"
        );
        let text = err.to_string();
        assert!(
            text.starts_with(&format!(
                "{}: scenario file: field `leader`",
                path.display()
            )),
            "{text}"
        );
    }

    #[test]
    fn a_setpoint_change_moves_the_formation() {
        let text = MINIMAL.replace("duration: 1.0", "duration: 6.0")
            + "setpoints: [{at: 1.0, l12: 1.5}]\n";
        let spec = ScenarioSpec::parse(&text, false, Path::new("x.yaml")).unwrap();
        // On the filter's estimate (the default control).
        let (run, _) = spec.run(1, false, &spec.filter_config(), true).unwrap();
        let l_end = run.samples.last().unwrap().truth[3];
        assert!((l_end - 1.5).abs() < 0.05, "l12 at the end {l_end}");
        // On the truth.
        let truth = ScenarioSpec::parse(&(text + "control: truth\n"), false, Path::new("x.yaml"))
            .unwrap()
            .simulate(1, false)
            .unwrap();
        let l_end = truth.samples.last().unwrap().truth[3];
        assert!((l_end - 1.5).abs() < 0.01, "l12 at the end {l_end}");
    }

    /// #30: `control` is read (estimate by default), and a bad value names the field.
    #[test]
    fn control_is_read_and_a_bad_value_named() {
        let spec = ScenarioSpec::parse(MINIMAL, false, Path::new("x.yaml")).unwrap();
        assert_eq!(spec.config(1, false).control, Control::Estimate);
        for (text, control) in [("truth", Control::Truth), ("open", Control::Open)] {
            let spec = ScenarioSpec::parse(
                &format!("{MINIMAL}control: {text}\n"),
                false,
                Path::new("x.yaml"),
            )
            .unwrap();
            assert_eq!(spec.config(1, false).control, control);
            assert_eq!(control.name(), text);
        }
        let err = ScenarioSpec::parse(
            &format!("{MINIMAL}control: oracle\n"),
            false,
            Path::new("x.yaml"),
        )
        .unwrap_err()
        .to_string();
        assert!(err.contains("control") && err.contains("oracle"), "{err}");
    }

    #[test]
    fn the_vision_section_defaults_to_the_built_in_demo() {
        let spec = ScenarioSpec::parse(MINIMAL, false, Path::new("x.yaml")).unwrap();
        assert_eq!(spec.vision, VisionSpec::default());
        assert_eq!(spec.vision.camera, CameraSpec::default());
        assert_eq!(
            spec.vision.occlusions,
            [OcclusionSpec { from: 3.5, to: 4.5 }]
        );
        let text = MINIMAL.to_owned()
            + "vision:\n  camera: {width: 320, height: 240, hfov_deg: 50}\n  render:\n    \
               motion_blur: {exposure_s: 0.01}\n    gradient: {from: 1, to: 0.5}\n  \
               occlusions: []\n";
        let spec = ScenarioSpec::parse(&text, false, Path::new("x.yaml")).unwrap();
        let v = &spec.vision;
        assert_eq!((v.camera.width, v.camera.height), (320, 240));
        assert_eq!(v.render.motion_blur.unwrap().subframes, 5);
        assert_eq!(v.render.gradient.unwrap().angle_deg, 0.0);
        assert_eq!(v.render.supersampling, 4);
        assert!(v.occlusions.is_empty());
    }

    #[test]
    fn bad_vision_fields_are_named() {
        for (section, what) in [
            ("camera: {width: 8, height: 240}", "vision.camera"),
            ("camera: {hfov_deg: 200}", "vision.camera.hfov_deg"),
            ("mount: {pan: 30}", "radians, not degrees"),
            ("render: {noise_sigma: -1}", "vision.render.noise_sigma"),
            ("render: {supersampling: 0}", "vision.render.supersampling"),
            (
                "render: {motion_blur: {exposure_s: 0.1}}",
                "at most the frame period",
            ),
            (
                "render: {motion_blur: {exposure_s: 0.01, subframes: 4}}",
                "must be odd",
            ),
            ("render: {gradient: {from: 1, to: -1}}", "gradient.to"),
            ("occlusions: [{from: 2, to: 1}]", "vision.occlusions[0]"),
            (
                "occlusions: [{from: 1, to: 2}, {from: 3, to: 4}]",
                "at most one",
            ),
            ("lens: fisheye", "unknown field"),
        ] {
            let text = format!("{MINIMAL}vision:\n  {section}\n");
            let err = ScenarioSpec::parse(&text, false, Path::new("x.yaml"))
                .unwrap_err()
                .to_string();
            assert!(err.contains(what), "{section}: {err}");
        }
    }
}
