//! `cargo xtask solvepnp`: OpenCV's single-marker poses and lens projections as reference data
//! for `pose`'s tests (`crates/pose/tests/opencv_reference.rs`).
//!
//! 1. The cases: a JSON file of cameras (`k`, `distortion_model`, `distortion`), marker corner
//!    sets (`camera`, `size` in metres, 4 corners `[u, v]` in OpenCV's order) and 3D points to
//!    project through each camera. Without `--cases FILE` it is generated here from seeded
//!    synthetic views (known poses, corners projected through the lens, 0.2 px Gaussian noise)
//!    and written to `fixtures/opencv/solvepnp_cases.json`; with it, any corner sets (e.g.
//!    real detections) are used as given.
//! 2. A Python virtual environment in `target/py-venv` with `opencv-contrib-python-headless`
//!    (created on first use) runs `cv2.solvePnPGeneric(..., SOLVEPNP_IPPE_SQUARE)` on every
//!    corner set (both solutions, each then refined with `cv2.solvePnPRefineLM`), and
//!    `cv2.projectPoints` / `cv2.fisheye.projectPoints` on the points. Each corner set is
//!    solved twice: OpenCV's own way (`solutions`: the distortion handed to `solvePnP`, whose
//!    refinement then minimises the error in distorted pixels; a fisheye camera's corners are
//!    undistorted with `cv2.fisheye.undistortPoints` first, as `solvePnP` takes no fisheye
//!    model), and on corners undistorted by `cv2.undistortPoints` to convergence
//!    (`undistorted_solutions`: the error in ideal pixels, the objective our solver
//!    minimises).
//! 3. The results go to `fixtures/opencv/solvepnp_opencv.json` (or `--out FILE`).
//!
//! `--duckietown` makes the cases from our own detections instead: `fiducial` (default
//! settings, tag36h11) reads the real frames of `fixtures/realdata/duckietown/`, and every
//! tag read becomes a corner set (65 mm, the frame set's K from `test_info.yaml`; the frames
//! are rectified, so both sides use the plumb-bob model with zero coefficients). They go to
//! `fixtures/opencv/duckietown_cases.json` and OpenCV's answers to
//! `fixtures/opencv/duckietown_opencv.json`, read by `crates/fiducial/tests/duckietown.rs`.

use std::path::{Path, PathBuf};

use pose::{Distortion, Intrinsics, Pose, marker_corners};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde_json::{Value, json};

/// The OpenCV package and version the reference data was made with.
/// Corner noise of the synthetic cases, pixels (standard deviation).
const NOISE_PX: f64 = 0.2;
/// Seed of the synthetic cases.
const SEED: u64 = 13;

const USAGE: &str = "usage: cargo xtask solvepnp [--cases FILE | --duckietown] [--out FILE]

  --cases FILE  corner sets to solve (default: generate synthetic ones into
                fixtures/opencv/solvepnp_cases.json)
  --duckietown  our detections on fixtures/realdata/duckietown as the corner sets (written to
                fixtures/opencv/duckietown_cases.json; results by default to
                fixtures/opencv/duckietown_opencv.json)
  --out FILE    OpenCV's results (default fixtures/opencv/solvepnp_opencv.json)";

pub fn run(args: &[String]) -> crate::Result {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let mut cases = None;
    let mut out = None;
    let mut duckietown = false;
    let mut it = args.iter();
    while let Some(a) = it.next() {
        match a.as_str() {
            "--cases" => cases = Some(PathBuf::from(it.next().ok_or(USAGE)?)),
            "--out" => out = Some(PathBuf::from(it.next().ok_or(USAGE)?)),
            "--duckietown" => duckietown = true,
            _ => return Err(USAGE.into()),
        }
    }
    if duckietown && cases.is_some() {
        return Err(USAGE.into());
    }
    let out = out.unwrap_or_else(|| {
        root.join(if duckietown {
            "fixtures/opencv/duckietown_opencv.json"
        } else {
            "fixtures/opencv/solvepnp_opencv.json"
        })
    });
    let cases = match cases {
        Some(path) => path,
        None if duckietown => {
            let path = root.join("fixtures/opencv/duckietown_cases.json");
            let text = serde_json::to_string_pretty(&duckietown_cases(&root)?)?;
            write(&path, &(text + "\n"))?;
            eprintln!("wrote {}", path.display());
            path
        }
        None => {
            let path = root.join("fixtures/opencv/solvepnp_cases.json");
            let text = serde_json::to_string_pretty(&synthetic_cases()?)?;
            write(&path, &(text + "\n"))?;
            eprintln!("wrote {}", path.display());
            path
        }
    };
    let python = crate::pyenv::python(
        &root,
        "solvepnp",
        &[crate::pyenv::OPENCV, crate::pyenv::NUMPY],
        "import cv2",
    )?;
    let script = root.join("target/solvepnp.py");
    write(&script, SCRIPT)?;
    crate::pyenv::run_script(&python, &script, &[&cases, &out])?;
    eprintln!("wrote {}", out.display());
    Ok(())
}

fn write(path: &Path, text: &str) -> crate::Result {
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir)?;
    }
    std::fs::write(path, text)?;
    Ok(())
}

/// One synthetic camera: name, image size, K (row-major), lens.
struct Camera {
    name: &'static str,
    width: f64,
    height: f64,
    k: [f64; 9],
    distortion: Distortion,
    /// Marker side, metres.
    size: f64,
    /// Distance range, metres.
    range: (f64, f64),
}

fn cameras() -> crate::Result<Vec<Camera>> {
    Ok(vec![
        Camera {
            // The Duckietown test frames' K (shared/realdata/duckietown/test_info.yaml,
            // multiple_tags_test) with an illustrative barrel distortion; tag36h11, 65 mm.
            name: "duckietown",
            width: 640.0,
            height: 480.0,
            k: crate::bags::DUCKIETOWN_K,
            distortion: Distortion::plumb_bob(-0.25, 0.05, 0.001, -0.0005, 0.0)?,
            size: 0.065,
            range: (0.2, 1.0),
        },
        Camera {
            name: "pinhole",
            width: 640.0,
            height: 480.0,
            k: [554.256, 0.0, 319.5, 0.0, 554.256, 239.5, 0.0, 0.0, 1.0],
            distortion: Distortion::NONE,
            size: 0.14,
            range: (0.5, 3.0),
        },
        Camera {
            // fixtures/calibration/ros_rational_polynomial.yaml
            name: "rational",
            width: 1280.0,
            height: 720.0,
            k: [900.0, 0.0, 639.5, 0.0, 900.0, 359.5, 0.0, 0.0, 1.0],
            distortion: Distortion::rational_polynomial([
                0.1, -0.02, 0.0006, -0.0004, 0.001, 0.35, 0.01, 0.001,
            ])?,
            size: 0.15,
            range: (0.5, 4.0),
        },
        Camera {
            // fixtures/calibration/ros_equidistant.yaml
            name: "fisheye",
            width: 1280.0,
            height: 800.0,
            k: [430.0, 0.0, 639.5, 0.0, 430.5, 399.5, 0.0, 0.0, 1.0],
            distortion: Distortion::equidistant(0.05, -0.01, 0.002, -0.0003)?,
            size: 0.10,
            range: (0.3, 1.5),
        },
    ])
}

/// Seeded synthetic corner sets: per camera, markers facing the camera within 50 degrees,
/// fully in the image, corners with 0.2 px Gaussian noise.
fn synthetic_cases() -> crate::Result<Value> {
    let mut rng = ChaCha8Rng::seed_from_u64(SEED);
    let gauss = |rng: &mut ChaCha8Rng| {
        // Box-Muller.
        let u1: f64 = rng.random_range(f64::EPSILON..1.0);
        let u2: f64 = rng.random_range(0.0..1.0);
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    };
    let mut cams = Vec::new();
    let mut cases = Vec::new();
    for cam in cameras()? {
        let k = Intrinsics::from_matrix(&nalgebra::Matrix3::from_row_slice(&cam.k))?;
        let model = marker_corners(cam.size, cam.size)?;
        let mut made = 0;
        let mut tries = 0;
        while made < 8 && tries < 10_000 {
            tries += 1;
            let z = rng.random_range(cam.range.0..cam.range.1);
            let (x, y) = (
                rng.random_range(-0.6..0.6) * z,
                rng.random_range(-0.4..0.4) * z,
            );
            let tilt = nalgebra::Rotation3::from_euler_angles(
                rng.random_range(-0.87..0.87),
                rng.random_range(-0.87..0.87),
                rng.random_range(-std::f64::consts::PI..std::f64::consts::PI),
            );
            let flip = nalgebra::Rotation3::from_axis_angle(
                &nalgebra::Vector3::x_axis(),
                std::f64::consts::PI,
            );
            let truth =
                Pose::from_matrix(&(flip * tilt).into_inner(), nalgebra::Vector3::new(x, y, z));
            let mut corners = Vec::new();
            for p in &model {
                let c = truth.transform_point(p);
                let Ok(m) = k.project(&c) else { break };
                let d = cam.distortion.distort_pixel(&k, &m);
                let (u, v) = (
                    d.x + NOISE_PX * gauss(&mut rng),
                    d.y + NOISE_PX * gauss(&mut rng),
                );
                if !(u >= 0.0 && v >= 0.0 && u <= cam.width - 1.0 && v <= cam.height - 1.0) {
                    break;
                }
                corners.push([u, v]);
            }
            if corners.len() < 4 {
                continue;
            }
            cases.push(json!({
                "name": format!("{}-{made}", cam.name),
                "camera": cam.name,
                "size": cam.size,
                "corners": corners,
                "truth": {
                    "rotation": truth.rotation.as_slice(),
                    "translation": truth.translation.as_slice(),
                },
            }));
            made += 1;
        }
        // Points to project: ideal pixels over the image, at depths 0.5 m to 2 m.
        let mut points = Vec::new();
        for (i, fu) in [0.02, 0.3, 0.5, 0.75, 0.98].iter().enumerate() {
            for fv in [0.02, 0.5, 0.98] {
                let m = nalgebra::Point2::new(fu * (cam.width - 1.0), fv * (cam.height - 1.0));
                let p = k.back_project_at_depth(&m, 0.5 + 0.375 * i as f64);
                points.push([p.x, p.y, p.z]);
            }
        }
        cams.push(json!({
            "name": cam.name,
            "width": cam.width,
            "height": cam.height,
            "k": cam.k,
            "distortion_model": cam.distortion.model().name(),
            "distortion": cam.distortion.coefficients(),
            "points": points,
        }));
    }
    Ok(json!({
        "generated_by": "cargo xtask solvepnp",
        "seed": SEED,
        "noise_px": NOISE_PX,
        "cameras": cams,
        "cases": cases,
    }))
}

/// The Duckietown frames and which `test_info.yaml` section (camera) each belongs to.
const DUCKIETOWN_FRAMES: &[(&str, &str)] = &[
    ("test_image.png", "sample_test"),
    ("test_image_multiple_01.png", "multiple_tags_test"),
    ("test_image_multiple_02.png", "multiple_tags_test"),
    ("test_image_multiple_03.png", "multiple_tags_test"),
    ("test_image_multiple_04.png", "multiple_tags_test"),
    ("test_image_multiple_05.png", "multiple_tags_test"),
    ("test_image_multiple_06.png", "multiple_tags_test"),
    ("test_image_multiple_07.png", "multiple_tags_test"),
    ("test_image_multiple_08.png", "multiple_tags_test"),
    ("test_image_multiple_09.png", "multiple_tags_test"),
    ("test_image_multiple_10.png", "multiple_tags_test"),
];

/// The `K:` list of each top-level section of `test_info.yaml` (a flat file: a section is
/// an unindented `name:` line, its `K: [...]` an indented line below it).
fn duckietown_k(text: &str) -> crate::Result<Vec<(String, [f64; 9])>> {
    let mut out = Vec::new();
    let mut section = None;
    for line in text.lines() {
        if !line.starts_with(' ') && line.trim_end().ends_with(':') {
            section = Some(line.trim_end().trim_end_matches(':').to_string());
        } else if let Some(list) = line.trim().strip_prefix("K:") {
            let values: Vec<f64> = list
                .trim()
                .trim_start_matches('[')
                .trim_end_matches(']')
                .split(',')
                .map(|v| v.trim().parse::<f64>())
                .collect::<Result<_, _>>()?;
            let k: [f64; 9] = values
                .try_into()
                .map_err(|_| "test_info.yaml: K must have 9 numbers")?;
            let name = section
                .clone()
                .ok_or("test_info.yaml: K outside a section")?;
            out.push((name, k));
        }
    }
    Ok(out)
}

/// Corner sets from our own detections on the Duckietown frames (see the module docs).
fn duckietown_cases(root: &Path) -> crate::Result<Value> {
    let dir = root.join("fixtures/realdata/duckietown");
    let ks = duckietown_k(&std::fs::read_to_string(dir.join("test_info.yaml"))?)?;
    let dict = fiducial::dictionary_by_name("tag36h11")?.clone();
    // Boundary clustering on: it reads the last one of the 56 tags (id 58 of frame 09).
    let config = fiducial::DetectorConfig {
        boundary_clusters: true,
        ..fiducial::DetectorConfig::default()
    };
    let mut det = fiducial::Detector::with_dictionary(config, dict);
    let mut out = Vec::new();
    let mut cases = Vec::new();
    for (file, camera) in DUCKIETOWN_FRAMES {
        let img = image::open(dir.join(file))?.to_luma8();
        let (w, h) = img.dimensions();
        det.detect(
            &fiducial::GrayView::new(img.as_raw(), w as usize, h as usize)?,
            &mut out,
        );
        out.sort_by_key(|d| d.index);
        for d in &out {
            cases.push(json!({
                "name": format!("{file}:{}", d.index),
                "camera": camera,
                "size": 0.065,
                "corners": d.corners.iter().map(|p| [p.x, p.y]).collect::<Vec<_>>(),
            }));
        }
    }
    let cams: Vec<Value> = ks
        .iter()
        .map(|(name, k)| {
            json!({
                "name": name,
                "width": 640.0,
                "height": 480.0,
                "k": k,
                "distortion_model": "plumb_bob",
                "distortion": [0.0, 0.0, 0.0, 0.0, 0.0],
                "points": [],
            })
        })
        .collect();
    Ok(json!({
        "generated_by": "cargo xtask solvepnp --duckietown",
        "detector": "fiducial, DetectorConfig::default() with boundary_clusters, tag36h11",
        "cameras": cams,
        "cases": cases,
    }))
}

/// Runs in the venv: `argv[1]` the cases, `argv[2]` the output.
const SCRIPT: &str = r#"
import json, sys
import numpy as np
import cv2

cases = json.load(open(sys.argv[1]))
cams = {c["name"]: c for c in cases["cameras"]}
EXACT = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-15)

def lens(c):
    k = np.array(c["k"], dtype=np.float64).reshape(3, 3)
    d = np.array(c["distortion"], dtype=np.float64)
    return k, d

def rms(a, b):
    a, b = a.reshape(-1, 2), b.reshape(-1, 2)
    return float(np.sqrt(np.mean(np.sum((a - b) ** 2, axis=1))))

def solve(obj, pts, k, dist):
    """Both IPPE_SQUARE solutions, each refined by LM, lower reprojection RMS first."""
    n, rvecs, tvecs, errs = cv2.solvePnPGeneric(obj, pts, k, dist, flags=cv2.SOLVEPNP_IPPE_SQUARE)
    sols = []
    for r, t, e in zip(rvecs, tvecs, np.array(errs).reshape(-1)):
        r2, t2 = cv2.solvePnPRefineLM(obj, pts, k, dist, r.copy(), t.copy(), criteria=EXACT)
        proj, _ = cv2.projectPoints(obj, r2, t2, k, dist)
        sols.append({
            "rotation": r2.reshape(-1).tolist(),
            "translation": t2.reshape(-1).tolist(),
            "rms_px": rms(proj, pts),
            "ippe_rotation": r.reshape(-1).tolist(),
            "ippe_translation": t.reshape(-1).tolist(),
            # OpenCV's figure: sqrt(sum of squared coordinate errors / 2N).
            "ippe_reprojection_error": float(e),
        })
    sols.sort(key=lambda x: x["rms_px"])
    return sols

out_cases = []
for case in cases["cases"]:
    cam = cams[case["camera"]]
    k, d = lens(cam)
    s = case["size"]
    obj = np.array([[-s / 2, s / 2, 0], [s / 2, s / 2, 0], [s / 2, -s / 2, 0], [-s / 2, -s / 2, 0]],
                   dtype=np.float64)
    img = np.array(case["corners"], dtype=np.float64).reshape(4, 1, 2)
    if cam["distortion_model"] == "equidistant":
        und = cv2.fisheye.undistortPoints(img, k, d, P=k, criteria=EXACT)
    else:
        und = cv2.undistortPoints(img, k, d, P=k, criteria=EXACT)
    none = np.zeros(5)
    # OpenCV's own way: the distortion handed to solvePnP (whose refinement then minimises
    # the error in distorted pixels); no fisheye model there, so undistorted corners.
    own = (und, none) if cam["distortion_model"] == "equidistant" else (img, d)
    out_cases.append({
        "name": case["name"],
        "solutions": solve(obj, own[0], k, own[1]),
        "undistorted_solutions": solve(obj, und, k, none),
    })

out_cams = []
for cam in cases["cameras"]:
    k, d = lens(cam)
    pts = np.array(cam["points"], dtype=np.float64).reshape(-1, 1, 3)
    zero = np.zeros(3)
    if len(pts) == 0:
        out_cams.append({"name": cam["name"], "pixels": []})
        continue
    if cam["distortion_model"] == "equidistant":
        proj, _ = cv2.fisheye.projectPoints(pts, zero, zero, k, d)
    else:
        proj, _ = cv2.projectPoints(pts, zero, zero, k, d)
    out_cams.append({"name": cam["name"], "pixels": proj.reshape(-1, 2).tolist()})

json.dump({
    "generated_by": cases.get("generated_by", "cargo xtask solvepnp"),
    "opencv": cv2.__version__,
    "cases": out_cases,
    "cameras": out_cams,
}, open(sys.argv[2], "w"), indent=1)
open(sys.argv[2], "a").write("\n")
"#;
