//! `cargo xtask bags`: the fixture ROS 2 bags in `fixtures/bags/`, written by an independent
//! implementation (the pure-Python `mcap-ros2-support` and `rosbags` packages, in a virtual
//! environment under `target/py-venv`), and what our folder path makes of the same frames
//! (`*.expected.jsonl`), which the tests compare the bag path with.
//!
//! 1. `formation-tracker demo --save-frames` renders the demo's raw frames, calibration
//!    and follower inputs; the first `--frames N` (default 16) become `demo_zstd.mcap`
//!    (mono8 `Image`, `CameraInfo`, `Odometry`, zstd chunks) and the first 2 `demo_lz4.mcap`
//!    (the same, lz4 chunks).
//! 2. Three real Duckietown frames (`../shared/realdata/duckietown`, BSD-2, notice copied
//!    beside the bag) become the rosbag2 folder `duckietown/` (metadata.yaml and an .mcap
//!    written by `rosbags`: PNG `CompressedImage` and `CameraInfo` from the set's K).
//! 3. `formation-tracker track` on the same frames as a folder (with `camera.yaml`,
//!    `inputs.csv`, `--fps 30`) writes `demo.expected.jsonl` and `duckietown.expected.jsonl`.
//! 4. `formation-tracker track BAG --mcap` runs on every bag, and the Python `mcap` reader
//!    (with `mcap-ros2-support` for the CDR images) reads each output back and checks every
//!    JSON message against its channel's JSON schema (`xtask/py/check_mcap.py`); the
//!    demo's `demo.mcap` from step 1 too.

use std::path::{Path, PathBuf};
use std::process::Command;

use crate::Result;

/// The Python packages, pinned.
const PACKAGES: &[&str] = &[
    "rosbags==0.11.9",
    "mcap==1.6.0",
    "mcap-ros2-support==0.6.0",
    crate::pyenv::NUMPY,
];

/// The Duckietown frames used (a subset: the fixtures stay small).
const DUCKIETOWN: &[&str] = &[
    "test_image_multiple_01.png",
    "test_image_multiple_05.png",
    "test_image_multiple_10.png",
];

/// K of the `multiple_tags_test` set (`test_info.yaml`).
pub const DUCKIETOWN_K: [f64; 9] = [
    338.563277422543,
    0.0,
    336.45495347495824,
    0.0,
    338.939280638548,
    230.486982216255,
    0.0,
    0.0,
    1.0,
];

/// Stamp of the first frame, nanoseconds (2023-11-14T22:13:20Z).
const BASE_NS: u64 = 1_700_000_000_000_000_000;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map_or_else(|| PathBuf::from("."), Path::to_path_buf)
}

fn check(status: std::process::ExitStatus, what: &str) -> Result {
    if status.success() {
        Ok(())
    } else {
        Err(format!("{what} failed ({status})").into())
    }
}

/// `formation-tracker ARGS` through cargo (the dev build), stdout returned.
fn tracker(root: &Path, args: &[&str]) -> Result<String> {
    let out = Command::new(env!("CARGO"))
        .current_dir(root)
        .args(["run", "-q", "-p", "formation-tracker-cli", "--", "--quiet"])
        .args(args)
        .stderr(std::process::Stdio::inherit())
        .output()?;
    check(out.status, &format!("formation-tracker {}", args.join(" ")))?;
    Ok(String::from_utf8(out.stdout)?)
}

fn stamp(i: usize) -> u64 {
    BASE_NS + (i as f64 * 1e9 / 30.0).round() as u64
}

/// Runs the command (`--frames N`).
pub fn run(args: &[String]) -> Result {
    let mut frames = 16usize;
    let mut it = args.iter();
    while let Some(a) = it.next() {
        match a.as_str() {
            "--frames" => {
                frames = it
                    .next()
                    .and_then(|s| s.parse().ok())
                    .filter(|n| (2..=240).contains(n))
                    .ok_or("--frames takes 2 to 240")?;
            }
            other => return Err(format!("bags: unknown option {other}").into()),
        }
    }
    let root = root();
    let work = root.join("target/bags");
    let fixtures = root.join("fixtures/bags");
    std::fs::create_dir_all(&work)?;
    std::fs::create_dir_all(&fixtures)?;
    let python = crate::pyenv::python(
        &root,
        "bags",
        PACKAGES,
        "import rosbags, mcap, mcap_ros2, numpy",
    )?;

    // 1. The demo's frames.
    let seq = work.join("seq");
    let demo_out = work.join("demo");
    tracker(
        &root,
        &[
            "demo",
            "--out",
            &demo_out.to_string_lossy(),
            "--save-frames",
            &seq.to_string_lossy(),
        ],
    )?;
    let csv = std::fs::read_to_string(seq.join("inputs.csv"))?;
    let rows: Vec<(f64, f64)> = csv
        .lines()
        .skip(1)
        .map(|l| {
            let f: Vec<f64> = l.split(',').filter_map(|x| x.parse().ok()).collect();
            (
                f.get(1).copied().unwrap_or(0.0),
                f.get(2).copied().unwrap_or(0.0),
            )
        })
        .collect();
    let folder = work.join("demo-frames");
    let raw = work.join("demo-raw");
    for d in [&folder, &raw] {
        if d.exists() {
            std::fs::remove_dir_all(d)?;
        }
        std::fs::create_dir_all(d)?;
    }
    let mut demo_frames = Vec::new();
    let mut inputs = String::from("frame,v2,w2\n");
    for i in 0..frames {
        let png = seq.join("frames").join(format!("frame-{i:04}.png"));
        std::fs::copy(&png, folder.join(format!("frame-{i:04}.png")))?;
        let img = image::open(&png)?.to_luma8();
        let raw_path = raw.join(format!("frame-{i:04}.gray"));
        std::fs::write(&raw_path, img.as_raw())?;
        let (v2, w2) = rows.get(i).copied().ok_or("inputs.csv is short")?;
        inputs.push_str(&format!("{i},{v2:?},{w2:?}\n"));
        demo_frames.push(serde_json::json!({
            "path": raw_path, "stamp_ns": stamp(i), "v2": v2, "w2": w2,
        }));
    }
    std::fs::write(work.join("demo-inputs.csv"), &inputs)?;
    let camera_yaml = std::fs::read_to_string(seq.join("camera.yaml"))?;
    let k = demo_k(&camera_yaml)?;

    // 2. Duckietown.
    let dt_dir = crate::realdata(&root, "duckietown")?;
    let dt_folder = work.join("duckietown-frames");
    if dt_folder.exists() {
        std::fs::remove_dir_all(&dt_folder)?;
    }
    std::fs::create_dir_all(&dt_folder)?;
    let mut dt_frames = Vec::new();
    for (i, name) in DUCKIETOWN.iter().enumerate() {
        let src = dt_dir.join(name);
        let dst = dt_folder.join(format!("{i:02}-{name}"));
        std::fs::copy(&src, &dst)?;
        dt_frames.push(serde_json::json!({ "path": src, "stamp_ns": stamp(i * 3) }));
    }
    // The source is read-only; a copy of it would be too, and the next run could not
    // replace it.
    let licence = std::fs::read(dt_dir.join("LICENSE.md"))?;
    let _ = std::fs::remove_file(fixtures.join("duckietown-LICENSE.md"));
    std::fs::write(fixtures.join("duckietown-LICENSE.md"), licence)?;
    let list = |k: &[f64]| {
        k.iter()
            .map(|x| format!("{x:?}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let dt_yaml = format!(
        "image_width: 640\nimage_height: 480\ncamera_name: duckietown\ncamera_matrix:\n  rows: 3\n  cols: 3\n  data: [{}]\ndistortion_model: plumb_bob\ndistortion_coefficients:\n  rows: 1\n  cols: 5\n  data: [0.0, 0.0, 0.0, 0.0, 0.0]\n",
        list(&DUCKIETOWN_K)
    );
    std::fs::write(work.join("duckietown-camera.yaml"), dt_yaml)?;

    let manifest = serde_json::json!({ "bags": [
        { "kind": "zstd", "out": fixtures.join("demo_zstd.mcap"), "encoding": "mono8",
          "width": 640, "height": 480, "k": k, "frames": demo_frames },
        { "kind": "lz4", "out": fixtures.join("demo_lz4.mcap"), "encoding": "mono8",
          "width": 640, "height": 480, "k": k, "frames": demo_frames[..2] },
        { "kind": "rosbag2", "out": fixtures.join("duckietown"), "encoding": "png",
          "width": 640, "height": 480, "k": DUCKIETOWN_K, "frames": dt_frames },
    ]});
    let manifest_path = work.join("manifest.json");
    std::fs::write(&manifest_path, serde_json::to_string_pretty(&manifest)?)?;
    crate::pyenv::run_script(
        &python,
        &root.join("xtask/py/make_bags.py"),
        &[&manifest_path],
    )?;

    // 3. The folder path on the same frames.
    let expected = tracker(
        &root,
        &[
            "track",
            &folder.to_string_lossy(),
            "--camera",
            &seq.join("camera.yaml").to_string_lossy(),
            "--inputs",
            &work.join("demo-inputs.csv").to_string_lossy(),
            "--fps",
            "30",
            "--json",
        ],
    )?;
    std::fs::write(fixtures.join("demo.expected.jsonl"), stable(&expected)?)?;
    let expected = tracker(
        &root,
        &[
            "track",
            &dt_folder.to_string_lossy(),
            "--camera",
            &work.join("duckietown-camera.yaml").to_string_lossy(),
            "--fps",
            "10",
            "--json",
        ],
    )?;
    std::fs::write(
        fixtures.join("duckietown.expected.jsonl"),
        stable(&expected)?,
    )?;

    // 4. Our output, read back by the Python reader.
    let mut outputs = Vec::new();
    for bag in ["demo_zstd.mcap", "demo_lz4.mcap", "duckietown"] {
        let out = work.join(format!("out-{}.mcap", bag.trim_end_matches(".mcap")));
        tracker(
            &root,
            &[
                "track",
                &fixtures.join(bag).to_string_lossy(),
                "--mcap",
                &out.to_string_lossy(),
                "--json",
            ],
        )?;
        outputs.push(out);
    }
    // The demo's own demo.mcap too.
    outputs.push(demo_out.join("demo.mcap"));
    crate::pyenv::run_script(&python, &root.join("xtask/py/check_mcap.py"), &outputs)?;
    let size: u64 = walk_size(&fixtures)?;
    println!(
        "bags: wrote {} ({:.1} MB); the Python mcap reader read our outputs back",
        fixtures.display(),
        size as f64 / 1e6
    );
    Ok(())
}

/// JSON lines without what changes from run to run or machine to machine: the wall-clock
/// `timing`, and the `source` path (kept as its file name).
fn stable(lines: &str) -> Result<String> {
    let mut out = String::new();
    for line in lines.lines() {
        let mut v: serde_json::Value = serde_json::from_str(line)?;
        if let Some(o) = v.as_object_mut() {
            o.remove("timing");
            if let Some(serde_json::Value::String(src)) = o.get_mut("source") {
                let name = Path::new(src.as_str())
                    .file_name()
                    .map(|n| n.to_string_lossy().into_owned())
                    .unwrap_or_default();
                *src = name;
            }
        }
        out.push_str(&serde_json::to_string(&v)?);
        out.push('\n');
    }
    Ok(out)
}

/// K from the demo's OpenCV `camera.yaml` (its `camera_matrix` data line).
fn demo_k(yaml: &str) -> Result<Vec<f64>> {
    let start = yaml
        .find("camera_matrix")
        .ok_or("camera.yaml has no camera_matrix")?;
    let data = &yaml[start..];
    let open = data.find('[').ok_or("camera_matrix has no data")?;
    let close = data.find(']').ok_or("camera_matrix has no data")?;
    let k: Vec<f64> = data[open + 1..close]
        .split(',')
        .map(|x| x.trim().parse::<f64>())
        .collect::<std::result::Result<_, _>>()?;
    if k.len() != 9 {
        return Err("camera_matrix is not 3x3".into());
    }
    Ok(k)
}

fn walk_size(dir: &Path) -> Result<u64> {
    let mut total = 0;
    for e in std::fs::read_dir(dir)? {
        let e = e?;
        let m = e.metadata()?;
        total += if m.is_dir() {
            walk_size(&e.path())?
        } else {
            m.len()
        };
    }
    Ok(total)
}
