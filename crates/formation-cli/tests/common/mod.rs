//! Helpers shared by the command tests.
#![allow(dead_code)] // each test binary uses its own subset

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use fiducial::Dictionary;
use formation_sim::scenario::{ScenarioConfig, simulate};
use formation_sim::scene::{CameraSpec, RenderSpec, RobotSpec, SceneSpec, render_scene};
use formation_tracker::mount::CameraMount;
use formation_tracker::rig::RigModel;
use unicycle::{PlanarPose, PolarModel};

/// A 640 x 480 pinhole calibration (60 deg horizontal field of view, no distortion), as
/// OpenCV writes it.
pub const CAMERA: &str = "%YAML:1.0
---
image_width: 640
image_height: 480
camera_matrix: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 554.2562584220408, 0., 319.5, 0., 554.2562584220408, 239.5, 0., 0., 1. ]
distortion_coefficients: !!opencv-matrix
   rows: 5
   cols: 1
   dt: d
   data: [ 0., 0., 0., 0., 0. ]
";

/// `track`'s arguments for a [`reference_clip`] folder (the command's current directory): its
/// frames, calibration and inputs at 30 fps, JSON lines.
pub const CLIP_ARGS: [&str; 8] = [
    "frames",
    "--camera",
    "camera.yaml",
    "--inputs",
    "inputs.csv",
    "--fps",
    "30",
    "--json",
];

/// A folder with a calibration and three blank 640x480 frames (nothing to find, but every
/// frame still prints a line).
pub fn blank_frames(name: &str) -> PathBuf {
    let d =
        PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(d.join("frames")).unwrap();
    std::fs::write(d.join("camera.yaml"), CAMERA).unwrap();
    for k in 0..3 {
        image::GrayImage::from_pixel(640, 480, image::Luma([128]))
            .save(d.join("frames").join(format!("f{k}.png")))
            .unwrap();
    }
    d
}

/// Runs the binary with `args` in `dir`, and returns what it did.
pub fn run(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_formation-tracker"))
        .args(args)
        .current_dir(dir)
        .output()
        .unwrap()
}

/// Frames of the reference scenario rendered for `track`, with their truth.
pub struct Clip {
    /// The folder: `frames/`, `inputs.csv`, `camera.yaml`.
    pub dir: PathBuf,
    /// The rendered frames.
    pub images: Vec<image::GrayImage>,
    /// The true `[l12, alpha12, beta12]` of each frame.
    pub truth: Vec<[f64; 3]>,
}

/// The first `frames` frames of the reference scenario, rendered (2 x 2 samples per pixel to
/// keep the tests fast), with the follower inputs CSV and the calibration, in a folder of
/// its own named after `name`.
pub fn reference_clip(name: &str, frames: usize) -> Clip {
    let dir = std::env::temp_dir().join(format!("ft-track-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("frames")).unwrap();
    let scenario = simulate(&ScenarioConfig::reference(1)).unwrap();
    let rig = RigModel::reference();
    let mut csv = String::from("frame,v2,w2\n");
    let (mut images, mut truth) = (Vec::new(), Vec::new());
    for (k, s) in scenario.samples.iter().take(frames).enumerate() {
        let prev = &scenario.samples[k.saturating_sub(1)];
        let leader = PolarModel::leader_pose(&s.truth);
        let spec = SceneSpec {
            name: String::new(),
            camera_robot: PlanarPose {
                x: s.follower.x,
                y: s.follower.y,
                theta: s.follower.theta,
            },
            mount: CameraMount::default(),
            camera: CameraSpec::default(),
            render: RenderSpec {
                supersampling: 2,
                seed: k as u64,
                ..RenderSpec::default()
            },
            robots: vec![RobotSpec {
                robot: 1,
                x: leader.x,
                y: leader.y,
                theta: leader.theta,
            }],
        };
        let image = render_scene(&spec, &rig, Dictionary::paper())
            .unwrap()
            .image;
        image
            .save(dir.join("frames").join(format!("f{k:03}.png")))
            .unwrap();
        images.push(image);
        let h = PolarModel::h(&s.truth);
        truth.push([h[0], h[1], h[2]]);
        csv += &format!(
            "{k},{},{}\n",
            prev.follower_inputs.v, prev.follower_inputs.w
        );
    }
    std::fs::write(dir.join("inputs.csv"), csv).unwrap();
    std::fs::write(dir.join("camera.yaml"), CAMERA).unwrap();
    Clip { dir, images, truth }
}

/// The lines of `reader` (a child's stdout or stderr) as they come, read on a thread of their
/// own, so that a test can wait for a line with a timeout instead of sleeping.
pub fn lines_of(reader: impl std::io::Read + Send + 'static) -> std::sync::mpsc::Receiver<String> {
    use std::io::BufRead as _;
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for line in std::io::BufReader::new(reader).lines() {
            let Ok(line) = line else { break };
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    rx
}

/// Every leader field of `got` (JSON lines of `track` or the node) equals `want`'s to 1e-9,
/// frame by frame; returns the number of leader estimates compared.
pub fn same_estimates(got: &[serde_json::Value], want: &[serde_json::Value]) -> usize {
    assert_eq!(got.len(), want.len(), "frame count");
    let mut leaders = 0;
    for (g, w) in got.iter().zip(want) {
        assert_eq!(g["frame"], w["frame"]);
        assert_eq!(g["markers"], w["markers"], "frame {}", w["frame"]);
        let (gl, wl) = (
            g["leaders"].as_array().unwrap(),
            w["leaders"].as_array().unwrap(),
        );
        assert_eq!(gl.len(), wl.len(), "frame {}", w["frame"]);
        for (a, b) in gl.iter().zip(wl) {
            assert_eq!(a["robot"], b["robot"]);
            assert_eq!(a["status"], b["status"]);
            for k in [
                "l12",
                "alpha12",
                "beta12",
                "v1",
                "w1",
                "l12_std",
                "alpha12_std",
                "beta12_std",
                "v1_std",
                "w1_std",
            ] {
                let (x, y) = (a[k].as_f64().unwrap(), b[k].as_f64().unwrap());
                assert!(
                    (x - y).abs() <= 1e-9,
                    "frame {} {k}: {x} vs {y}",
                    w["frame"]
                );
            }
            leaders += 1;
        }
        let (tg, tw) = (g["t"].as_f64().unwrap(), w["t"].as_f64().unwrap());
        assert!((tg - tw).abs() < 1e-6, "t {tg} vs {tw}");
    }
    leaders
}
