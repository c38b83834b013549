//! The robot stage of `formation-tracker detect`: options `--camera`, `--rig`, `--pan`,
//! `--mount`, `--free-pose`, and filling each image's `robots` from the markers read.
//!
//! Kept apart from `detect.rs` so the detector's command stays small: `detect` flattens
//! [`RobotArgs`] into its arguments, builds a [`RobotStage`] once and calls
//! [`RobotStage::measure`] per image.

use std::path::PathBuf;

use clap::Args as ClapArgs;
use fiducial::{Decoded, Dictionary};
use formation_tracker::mount::CameraMount;
use formation_tracker::rig::RigModel;
use formation_tracker::robots::{
    MarkerObservation, RobotConfig, RobotError, RobotMeasurement, measure_robots,
};
use pose::Camera;
use pose::PoseSolver;

use super::CliError;

/// Options of the robot stage.
#[derive(Debug, Clone, ClapArgs)]
pub struct RobotArgs {
    /// Camera calibration (OpenCV FileStorage or ROS camera_info YAML). With it, `robots`
    /// is filled: one joint pose per robot and its formation variables.
    #[arg(long, value_name = "FILE")]
    pub camera: Option<PathBuf>,
    /// Rig file (YAML/JSON: faces, geometry, the marker of each robot and face); default:
    /// the reference rig of spec 3.3.
    #[arg(long, value_name = "FILE")]
    pub rig: Option<PathBuf>,
    /// Camera pan about the follower's vertical axis, radians, left positive.
    #[arg(long, value_name = "RAD", value_parser = super::numbers::angle,
          allow_hyphen_values = true)]
    pub pan: Option<f64>,
    /// Camera mount as `OFFSET,HEIGHT[,TILT]`: metres ahead of the follower's reference
    /// point, metres above the ground, radians down. Default `0.5,0.30,0` (the reference
    /// mount).
    #[arg(long, value_name = "D,H[,TILT]", allow_hyphen_values = true)]
    pub mount: Option<String>,
    /// Report the free 6-DOF pose instead of refining it on the ground plane.
    #[arg(long = "free-pose")]
    pub free_pose: bool,
    /// Accept images whose size differs from the calibration's by scaling the intrinsics,
    /// for images resized from the calibrated camera's (same aspect ratio). Without it such
    /// an image is an error: its poses would be wrong by the scale.
    #[arg(long = "scale-calibration")]
    pub scale_calibration: bool,
}

/// Parses `OFFSET,HEIGHT[,TILT]`.
fn parse_mount(text: &str, pan: f64) -> Result<CameraMount, CliError> {
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    if !(2..=3).contains(&parts.len()) {
        return Err(super::Usage(format!(
            "--mount {text}: expected OFFSET,HEIGHT or OFFSET,HEIGHT,TILT (metres, metres, radians)"
        ))
        .into());
    }
    let mut v = [0.0; 3];
    type Check = fn(&str) -> Result<f64, String>;
    let checks: [(&str, Check); 3] = [
        ("OFFSET", super::numbers::offset),
        ("HEIGHT", super::numbers::height),
        ("TILT", super::numbers::tilt),
    ];
    for (i, p) in parts.iter().enumerate() {
        let (name, check) = checks[i];
        v[i] = check(p).map_err(|e| super::Usage(format!("--mount {text}: {name} `{p}`: {e}")))?;
    }
    Ok(CameraMount {
        offset: v[0],
        height: v[1],
        pan,
        tilt: v[2],
    })
}

/// Everything needed to turn the markers of an image into robots.
#[derive(Debug, Clone)]
pub struct RobotStage {
    /// The rig.
    pub rig: RigModel,
    calibration: Camera,
    scale_calibration: bool,
    mount: CameraMount,
    config: RobotConfig,
}

impl RobotStage {
    /// The rig of `args` (reference when none) whether or not a camera is given.
    pub fn rig(args: &RobotArgs, dictionary: &Dictionary) -> Result<RigModel, CliError> {
        super::load_rig(args.rig.as_deref(), dictionary)
    }

    /// The stage, or `None` without `--camera`.
    pub fn from_args(args: &RobotArgs, dictionary: &Dictionary) -> Result<Option<Self>, CliError> {
        let pan = args.pan.unwrap_or(0.0);
        let mount = match &args.mount {
            Some(text) => parse_mount(text, pan)?,
            None => CameraMount {
                pan,
                ..CameraMount::default()
            },
        };
        let Some(path) = &args.camera else {
            if args.mount.is_some() || args.pan.is_some() || args.free_pose {
                return Err(super::Usage(
                    "--mount, --pan and --free-pose need --camera FILE".into(),
                )
                .into());
            }
            return Ok(None);
        };
        let calib =
            Camera::from_file(path).map_err(|e| format!("--camera {}: {e}", path.display()))?;
        Ok(Some(Self {
            rig: Self::rig(args, dictionary)?,
            calibration: calib,
            scale_calibration: args.scale_calibration,
            mount,
            config: RobotConfig {
                ground_plane: !args.free_pose,
                ..RobotConfig::default()
            },
        }))
    }

    /// The calibration for a `width x height` image: the file's, or scaled to the image with
    /// `--scale-calibration`; an image of another size is an error otherwise.
    pub fn calibration_for(&self, width: u32, height: u32) -> Result<Camera, CliError> {
        if self.scale_calibration {
            Ok(self.calibration.scaled_to(width, height)?)
        } else {
            self.calibration.check_size(width, height).map_err(|e| {
                format!("{e} (pass --scale-calibration if the image was resized from the calibrated camera's)")
            })?;
            Ok(self.calibration)
        }
    }

    /// The robots seen in a `width x height` image from its markers (corners undistorted
    /// first), and the robots whose pose failed or was rejected as implausible (also
    /// reported on stderr). An image whose size is not the calibration's is an error, unless
    /// `--scale-calibration` was given.
    pub fn measure(
        &self,
        markers: &[Decoded],
        width: u32,
        height: u32,
    ) -> Result<(Vec<RobotMeasurement>, Vec<RobotError>), CliError> {
        let calibration = self.calibration_for(width, height)?;
        let (intrinsics, distortion) = (calibration.intrinsics, calibration.distortion);
        let solver = PoseSolver::new(intrinsics);
        let observations: Vec<MarkerObservation> = markers
            .iter()
            .filter_map(|d| {
                let mut corners = d.corners;
                for c in &mut corners {
                    *c = distortion.undistort_pixel(&intrinsics, c).ok()?;
                }
                Some(MarkerObservation {
                    index: d.index,
                    corners,
                })
            })
            .collect();
        let found = measure_robots(&observations, &self.rig, &solver, &self.mount, &self.config);
        for f in &found.failures {
            super::progress::errln!("formation-tracker: warning: {f}");
        }
        Ok((found.robots, found.failures))
    }
}
