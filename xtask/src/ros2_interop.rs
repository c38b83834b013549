//! `cargo xtask ros2-interop`: `formation-tracker ros2` against an independent DDS
//! implementation, CycloneDDS (the DDS behind ROS 2's `rmw_cyclonedds`), through its Python
//! binding (pip `cyclonedds`, in the venv under `target/py-venv`). Done-when of #34.
//!
//! 1. The release binary is built, and `demo --save-frames` records the demo's frames,
//!    calibration and follower inputs in `target/ros2-interop/seq` (kept for the next run);
//!    the frames are also written as raw grey bytes (`raw/`), so that the Python side needs
//!    nothing but `cyclonedds`.
//! 2. In one private user and network namespace (`unshare --user --map-root-user --net`,
//!    only the loopback, multicast routed to it, CycloneDDS pinned to it by
//!    `CYCLONEDDS_URI`): the node runs with `--json --max-frames N`, and
//!    `xtask/py/ros2_interop.py` publishes the frames as a camera driver would (mono8
//!    `Image`, `CameraInfo`, `Odometry` at 30 Hz on `rt/image_raw`, `rt/camera_info`,
//!    `rt/odom`, ROS 2's type names, XCDR1), reads every topic the node publishes, decodes
//!    every message and checks it against the node's JSON lines (the formation arrays to
//!    1e-12), and the node's lines against `track` on the same files (the script's
//!    docstring lists every check).
//! 3. The script's table is printed; any failed check ends the command with its reason.
//!    Every message the node publishes must arrive. `--lenient` reports and tolerates two
//!    losses the node had before it made its leaders' writers at start (`--leaders`) and
//!    lingered on exit: the first message on a new leader's topics, written before RustDDS
//!    matched the new writer with our readers, and the last frame's messages, not yet sent
//!    when `--max-frames` ended the node.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use crate::Result;

/// CycloneDDS's Python binding, pinned (11.0.1: the first with wheels for this Python;
/// the C library is in the wheel, nothing is compiled).
const CYCLONEDDS: &str = "cyclonedds==11.0.1";

/// Frames per second of the published recording.
const FPS: f64 = 30.0;

/// Leader ids subscribed to before the node starts (its leader topics appear with a leader).
const LEADER_IDS: std::ops::RangeInclusive<u32> = 1..=8;

/// Pins CycloneDDS to the loopback, with multicast (the namespace routes it there).
const CYCLONEDDS_XML: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<CycloneDDS xmlns="https://cdds.io/config">
  <Domain Id="any">
    <General>
      <Interfaces>
        <NetworkInterface name="lo" multicast="true"/>
      </Interfaces>
      <AllowMulticast>true</AllowMulticast>
    </General>
    <Tracing>
      <Verbosity>warning</Verbosity>
      <OutputFile>cyclonedds.log</OutputFile>
    </Tracing>
  </Domain>
</CycloneDDS>
"#;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map_or_else(|| PathBuf::from("."), Path::to_path_buf)
}

/// Runs the command (`--frames N`, default 150: through the demo's occlusion at 3.5-4.5 s,
/// so that the leader is seen tracking and coasting; `--lenient`: tolerate the two losses
/// described in the module documentation).
pub fn run(args: &[String]) -> Result {
    let mut frames = 150usize;
    let mut strict = true;
    let mut it = args.iter();
    while let Some(a) = it.next() {
        match a.as_str() {
            "--lenient" => strict = false,
            "--frames" => {
                frames = it
                    .next()
                    .and_then(|s| s.parse().ok())
                    .filter(|n| (2..=200).contains(n))
                    .ok_or("--frames takes 2 to 200")?;
            }
            other => return Err(format!("ros2-interop: unknown option {other}").into()),
        }
    }
    let started = Instant::now();
    let root = root();
    let work = root.join("target/ros2-interop");
    std::fs::create_dir_all(&work)?;
    namespace_available()?;

    // 1. The binary and the recording.
    let status = Command::new(env!("CARGO"))
        .current_dir(&root)
        .args(["build", "--release", "-q", "-p", "formation-tracker-cli"])
        .status()?;
    if !status.success() {
        return Err(
            format!("cargo build --release -p formation-tracker-cli failed ({status})").into(),
        );
    }
    let target =
        std::env::var_os("CARGO_TARGET_DIR").map_or_else(|| root.join("target"), PathBuf::from);
    let bin = target.join("release/formation-tracker");
    let seq = work.join("seq");
    let recorded = seq.join("inputs.csv").exists()
        && seq.join("camera.yaml").exists()
        && seq.join("frames").is_dir();
    if recorded {
        eprintln!("ros2-interop: reusing the recording in {}", seq.display());
    } else {
        eprintln!("ros2-interop: recording the demo into {}", seq.display());
        let status = Command::new(&bin)
            .arg("--quiet")
            .arg("demo")
            .arg("--out")
            .arg(work.join("demo"))
            .arg("--save-frames")
            .arg(&seq)
            .status()?;
        if !status.success() {
            return Err(format!("formation-tracker demo --save-frames failed ({status})").into());
        }
    }
    let mut manifest = write_inputs(&work, &seq)?;
    manifest["strict"] = serde_json::Value::Bool(strict);
    let have = manifest["frames"].as_array().map_or(0, Vec::len);
    if have < frames + 10 {
        return Err(format!(
            "the recording has {have} frames; --frames {frames} needs {} (frames the node skips are replaced by later ones)",
            frames + 10
        )
        .into());
    }

    // What `track` makes of the same frames from the files: the node, fed by CycloneDDS,
    // must give the same lines (when it tracked every frame).
    let track_frames = work.join("track-frames");
    if track_frames.exists() {
        std::fs::remove_dir_all(&track_frames)?;
    }
    std::fs::create_dir_all(&track_frames)?;
    for i in 0..frames {
        let name = format!("frame-{i:04}.png");
        std::fs::copy(seq.join("frames").join(&name), track_frames.join(&name))?;
    }
    let track = Command::new(&bin)
        .arg("track")
        .arg(&track_frames)
        .arg("--camera")
        .arg(seq.join("camera.yaml"))
        .arg("--inputs")
        .arg(seq.join("inputs.csv"))
        .args(["--fps", "30", "--json", "--quiet"])
        .output()?;
    if !track.status.success() {
        return Err(format!(
            "formation-tracker track failed ({}): {}",
            track.status,
            String::from_utf8_lossy(&track.stderr)
        )
        .into());
    }
    std::fs::write(work.join("track.jsonl"), &track.stdout)?;
    manifest["track_jsonl"] = serde_json::json!(work.join("track.jsonl"));

    // 2. CycloneDDS in the venv, and its configuration.
    let python = crate::pyenv::python(
        &root,
        "ros2-interop",
        &[CYCLONEDDS],
        "import cyclonedds.idl, cyclonedds.domain",
    )?;
    let config = work.join("cyclonedds.xml");
    std::fs::write(&config, CYCLONEDDS_XML)?;
    let manifest_path = work.join("manifest.json");
    std::fs::write(&manifest_path, serde_json::to_string_pretty(&manifest)?)?;
    for f in ["node.jsonl", "node.err", "summary.json", "cyclonedds.log"] {
        let _ = std::fs::remove_file(work.join(f));
    }

    // 3. The node and CycloneDDS in one private namespace.
    let script = format!(
        "set -e; ip link set lo up; ip link set lo multicast on; ip route add 224.0.0.0/4 dev lo; \
         export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST ROS_DOMAIN_ID=17 \
         CYCLONEDDS_URI=\"file://$CONFIG\"; set +e; \
         \"$BIN\" ros2 --json --max-frames {frames} > node.jsonl 2> node.err & node=$!; \
         \"$PYTHON\" \"$SCRIPT\" manifest.json $node; py=$?; \
         if [ $py -ne 0 ]; then kill -INT $node 2>/dev/null; fi; \
         wait $node; nd=$?; \
         if [ $nd -ne 0 ]; then echo \"ros2-interop: FAILED: the node exited with $nd\"; fi; \
         [ $py -eq 0 ] && [ $nd -eq 0 ]"
    );
    let out = Command::new("unshare")
        .args(["--user", "--map-root-user", "--net", "bash", "-c", &script])
        .current_dir(&work)
        .env("BIN", &bin)
        .env("PYTHON", &python)
        .env("SCRIPT", root.join("xtask/py/ros2_interop.py"))
        .env("CONFIG", &config)
        .env_remove("CYCLONEDDS_HOME")
        .stderr(std::process::Stdio::inherit())
        .output()?;
    let text = String::from_utf8_lossy(&out.stdout);
    print!("{text}");
    let node_err = std::fs::read_to_string(work.join("node.err")).unwrap_or_default();
    let node_summary = node_err
        .lines()
        .rfind(|l| l.contains("frames tracked of"))
        .unwrap_or("(the node printed no summary)");
    println!("node: {}", node_summary.trim_start_matches("ros2: "));
    // The other direction: the node could use every Image, CameraInfo and Odometry it took.
    if out.status.success() && !node_summary.contains("), 0 unusable, 0 unusable inputs") {
        return Err(
            "the node's summary counts unusable frames or inputs: it could not use messages CycloneDDS sent"
                .into(),
        );
    }
    if !out.status.success() {
        let reason = text.lines().rfind(|l| l.contains("FAILED")).map_or_else(
            || format!("the namespace script failed ({})", out.status),
            |l| l.trim_start_matches("ros2-interop: FAILED: ").to_owned(),
        );
        eprintln!(
            "ros2-interop: the node's log is {}, CycloneDDS's {}",
            work.join("node.err").display(),
            work.join("cyclonedds.log").display()
        );
        return Err(reason.into());
    }
    println!(
        "ros2-interop: passed in {:.1} s (CycloneDDS {} and formation-tracker ros2 in a private network namespace)",
        started.elapsed().as_secs_f64(),
        CYCLONEDDS.trim_start_matches("cyclonedds==")
    );
    Ok(())
}

/// Fails with a clear message when unprivileged user and network namespaces are not there.
fn namespace_available() -> Result {
    let probe = Command::new("unshare")
        .args([
            "--user",
            "--map-root-user",
            "--net",
            "ip",
            "link",
            "set",
            "lo",
            "up",
        ])
        .output();
    match probe {
        Ok(o) if o.status.success() => Ok(()),
        Ok(o) => Err(format!(
            "ros2-interop needs a private network namespace, and `unshare --user --map-root-user --net` failed: {} (are unprivileged user namespaces allowed? is `ip` from iproute2 installed?)",
            String::from_utf8_lossy(&o.stderr).trim()
        )
        .into()),
        Err(e) => Err(format!(
            "ros2-interop needs `unshare` (util-linux) for a private network namespace: {e}"
        )
        .into()),
    }
}

/// Writes the frames as raw grey bytes and returns the script's manifest: the calibration
/// (as `ros2-sim` publishes it), and per frame its raw file and the follower's `(v2, w2)`.
fn write_inputs(work: &Path, seq: &Path) -> Result<serde_json::Value> {
    let camera = pose::Camera::from_file(seq.join("camera.yaml"))
        .map_err(|e| format!("{}: {e}", seq.join("camera.yaml").display()))?;
    let k = camera.intrinsics.matrix();
    let k: Vec<f64> = (0..3)
        .flat_map(|r| (0..3).map(move |c| (r, c)))
        .map(|(r, c)| k[(r, c)])
        .collect();
    let csv = std::fs::read_to_string(seq.join("inputs.csv"))?;
    let inputs: Vec<(f64, f64)> = csv
        .lines()
        .skip(1)
        .map(|l| {
            let f: Vec<f64> = l.split(',').filter_map(|x| x.parse().ok()).collect();
            match f[..] {
                [_, v, w] => Ok((v, w)),
                _ => Err(format!("inputs.csv: bad line {l:?}")),
            }
        })
        .collect::<std::result::Result<_, _>>()?;
    let mut pngs: Vec<PathBuf> = std::fs::read_dir(seq.join("frames"))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "png"))
        .collect();
    pngs.sort();
    let raw = work.join("raw");
    std::fs::create_dir_all(&raw)?;
    let bytes = camera.width as u64 * camera.height as u64;
    let mut frames = Vec::new();
    for (i, png) in pngs.iter().enumerate() {
        let Some(&(v2, w2)) = inputs.get(i) else {
            break;
        };
        let path = raw.join(format!("frame-{i:04}.gray"));
        if std::fs::metadata(&path).map_or(true, |m| m.len() != bytes) {
            let img = image::open(png)?.to_luma8();
            if (img.width(), img.height()) != (camera.width, camera.height) {
                return Err(
                    format!("{}: not {}x{}", png.display(), camera.width, camera.height).into(),
                );
            }
            std::fs::write(&path, img.as_raw())?;
        }
        frames.push(serde_json::json!({ "path": path, "v2": v2, "w2": w2 }));
    }
    Ok(serde_json::json!({
        "fps": FPS,
        "width": camera.width,
        "height": camera.height,
        "k": k,
        "d": camera.distortion.coefficients(),
        "distortion_model": camera.distortion.model().name(),
        "leader_ids": LEADER_IDS.collect::<Vec<_>>(),
        "node_jsonl": work.join("node.jsonl"),
        "summary": work.join("summary.json"),
        "frames": frames,
    }))
}
