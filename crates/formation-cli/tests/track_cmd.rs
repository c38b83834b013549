//! The `track` command end to end on frames rendered by the synthetic camera: a folder of
//! PNGs (one of them broken) and a y4m stream on stdin (truncated), with and without the
//! follower-inputs CSV.
#![allow(clippy::unwrap_used)] // Tests may unwrap (house rules); helpers here are test code too.

use std::io::Write;
use std::path::Path;
use std::process::{Command, Stdio};

use unicycle::wrap_angle;

mod common;

const FRAMES: usize = 12;

fn track(args: &[&str], dir: &Path, stdin: Option<Vec<u8>>) -> (String, String, Option<i32>) {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_formation-tracker"));
    cmd.arg("track")
        .args(args)
        .current_dir(dir)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    let mut child = cmd.spawn().unwrap();
    let mut pipe = child.stdin.take().unwrap();
    if let Some(bytes) = stdin {
        pipe.write_all(&bytes).unwrap();
    }
    drop(pipe);
    let out = child.wait_with_output().unwrap();
    (
        String::from_utf8(out.stdout).unwrap(),
        String::from_utf8(out.stderr).unwrap(),
        out.status.code(),
    )
}

fn lines(stdout: &str) -> Vec<serde_json::Value> {
    stdout
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

#[test]
fn folder_with_a_broken_frame() {
    let clip = common::reference_clip("folder", FRAMES);
    std::fs::write(clip.dir.join("frames").join("f005.png"), b"broken").unwrap();
    let (stdout, stderr, code) = track(&common::CLIP_ARGS, &clip.dir, None);
    // Exit code 3: partial, one frame could not be used (docs/reliability.md).
    assert_eq!(code, Some(3), "{stderr}");
    assert!(
        stderr.contains("warning: 11 frames tracked, 1 broken"),
        "{stderr}"
    );
    // The broken file is named, not numbered as a frame.
    assert!(
        stderr.contains("f005.png: ")
            && stderr.contains("(skipped)")
            && !stderr.contains("frame 5"),
        "{stderr}"
    );
    assert!(!stderr.contains("stands still"), "{stderr}");
    let frames = lines(&stdout);
    assert_eq!(frames.len(), FRAMES - 1);
    for f in &frames {
        let k = f["frame"].as_u64().unwrap() as usize;
        assert_ne!(k, 5);
        assert_eq!(f["source"], format!("frames/f{k:03}.png"));
        assert!((f["t"].as_f64().unwrap() - k as f64 / 30.0).abs() < 1e-12);
        assert!(f["timing"]["detect_ms"].as_f64().unwrap() >= 0.0);
        let leaders = f["leaders"].as_array().unwrap();
        assert_eq!(leaders.len(), 1);
        let l = &leaders[0];
        assert_eq!(l["robot"], 1);
        assert_eq!(l["status"], "tracking", "frame {k}: {l}");
        for key in ["l12_std", "alpha12_std", "beta12_std", "v1_std", "w1_std"] {
            assert!(l[key].as_f64().unwrap() >= 0.0);
        }
        let truth = clip.truth[k];
        assert!((l["l12"].as_f64().unwrap() - truth[0]).abs() < 0.02, "{l}");
        assert!(
            wrap_angle(l["alpha12"].as_f64().unwrap() - truth[1]).abs() < 0.03,
            "{l}"
        );
        assert!(
            wrap_angle(l["beta12"].as_f64().unwrap() - truth[2]).abs() < 0.02,
            "{l}"
        );
    }
    // The frame after the broken one bridges the gap with two steps, still tracking.
    assert_eq!(frames[5]["frame"], 6);
    std::fs::remove_dir_all(&clip.dir).unwrap();
}

/// A y4m stream (mono) of the clip on stdin, cut inside its last frame.
#[test]
fn truncated_y4m_on_stdin_without_inputs() {
    let clip = common::reference_clip("stdin", FRAMES);
    let mut y4m = b"YUV4MPEG2 W640 H480 F30:1 Ip A1:1 Cmono\n".to_vec();
    for image in &clip.images {
        y4m.extend_from_slice(b"FRAME\n");
        y4m.extend_from_slice(image.as_raw());
    }
    y4m.truncate(y4m.len() - 1000);
    let (stdout, stderr, code) = track(&["-", "--camera", "camera.yaml"], &clip.dir, Some(y4m));
    // Exit code 3: partial, the last frame was cut off.
    assert_eq!(code, Some(3), "{stderr}");
    assert!(stderr.contains("stands still"), "{stderr}");
    assert!(stderr.contains("truncated"), "{stderr}");
    assert!(
        stderr.contains(&format!("{} frames tracked", FRAMES - 1)),
        "{stderr}"
    );
    let text: Vec<&str> = stdout.lines().collect();
    assert_eq!(text.len(), FRAMES - 1);
    assert!(
        text[0].starts_with("frame 0 t 0.000: robot 1 Tracking"),
        "{}",
        text[0]
    );
    std::fs::remove_dir_all(&clip.dir).unwrap();
}

#[test]
fn bad_arguments_are_one_line_errors() {
    let dir = std::env::temp_dir();
    let (_, stderr, code) = track(
        &["/nonexistent/frames", "--camera", "/nonexistent/cam.yaml"],
        &dir,
        None,
    );
    assert_eq!(code, Some(1), "{stderr}");
    assert_eq!(stderr.trim().lines().count(), 1, "{stderr}");
}

/// Regression (#11): with a mount tilt of the wrong sign, poses 170 px off their corners
/// reached the tracker (l12 of thousands of metres, status "tracking"). They are rejected
/// with their reason in `failures`, and no leader is tracked.
#[test]
fn poses_from_a_wrong_mount_are_rejected_not_tracked() {
    let clip = common::reference_clip("wrong-mount", FRAMES);
    let (stdout, stderr, code) = track(
        &[
            "frames",
            "--camera",
            "camera.yaml",
            "--mount-tilt",
            "0.3",
            "--json",
        ],
        &clip.dir,
        None,
    );
    assert_eq!(code, Some(0), "{stderr}");
    let frames = lines(&stdout);
    assert_eq!(frames.len(), FRAMES);
    for f in &frames {
        assert!(f["leaders"].as_array().unwrap().is_empty(), "{f}");
        let failures = f["failures"].as_array().unwrap();
        assert!(
            failures
                .iter()
                .any(|r| r.as_str().unwrap().contains("pose rejected: reprojection")),
            "{f}"
        );
    }
}

/// Each JSON line names its source: the image file, or `INPUT#N` for a y4m stream.
#[test]
fn json_lines_name_the_source_of_each_frame() {
    let d = common::blank_frames("track-source");
    let mut y4m = b"YUV4MPEG2 W640 H480 F30:1 Ip A1:1 Cmono\n".to_vec();
    for _ in 0..2 {
        y4m.extend_from_slice(b"FRAME\n");
        y4m.extend(std::iter::repeat_n(128u8, 640 * 480));
    }
    let (stdout, stderr, code) = track(&["-", "--camera", "camera.yaml", "--json"], &d, Some(y4m));
    assert_eq!(code, Some(0), "{stderr}");
    let sources: Vec<String> = lines(&stdout)
        .iter()
        .map(|l| l["source"].as_str().unwrap().to_string())
        .collect();
    assert_eq!(sources, ["-#0", "-#1"]);
    let (stdout, _, code) = track(&["frames", "--camera", "camera.yaml", "--json"], &d, None);
    assert_eq!(code, Some(0));
    let sources: Vec<String> = lines(&stdout)
        .iter()
        .map(|l| l["source"].as_str().unwrap().to_string())
        .collect();
    assert_eq!(sources, ["frames/f0.png", "frames/f1.png", "frames/f2.png"]);
}

/// `--guided` (#12): the same leaders and estimates close to the full-frame run's; frames
/// between the periodic full scans are searched in the predicted regions only, and every
/// line says how it was searched.
#[test]
fn guided_mode_tracks_as_full_frame_does() {
    let clip = common::reference_clip("guided", FRAMES);
    let base = common::CLIP_ARGS;
    let (full_out, stderr, code) = track(&base, &clip.dir, None);
    assert_eq!(code, Some(0), "{stderr}");
    let mut args = base.to_vec();
    args.extend(["--guided", "--full-scan-every", "5"]);
    let (guided_out, stderr, code) = track(&args, &clip.dir, None);
    assert_eq!(code, Some(0), "{stderr}");
    let (full, guided) = (lines(&full_out), lines(&guided_out));
    assert_eq!(full.len(), guided.len());
    let mut in_regions = 0;
    for (a, b) in full.iter().zip(&guided) {
        assert_eq!(a["scan"]["mode"], "full");
        assert_eq!(a["scan"]["factor"], 1);
        match b["scan"]["mode"].as_str().unwrap() {
            "guided" => {
                in_regions += 1;
                assert!(b["scan"]["pixels"].as_u64().unwrap() > 0);
            }
            mode => assert_eq!(mode, "full"),
        }
        let ids = |f: &serde_json::Value| -> Vec<u64> {
            f["leaders"]
                .as_array()
                .unwrap()
                .iter()
                .map(|l| l["robot"].as_u64().unwrap())
                .collect()
        };
        assert_eq!(ids(a), ids(b), "frame {}", a["frame"]);
        for (la, lb) in a["leaders"]
            .as_array()
            .unwrap()
            .iter()
            .zip(b["leaders"].as_array().unwrap())
        {
            assert_eq!(la["status"], lb["status"]);
            let (x, y) = (la["l12"].as_f64().unwrap(), lb["l12"].as_f64().unwrap());
            assert!(
                (x - y).abs() < 0.01,
                "frame {}: l12 {x} against {y}",
                a["frame"]
            );
        }
    }
    // Frame 0 and every fifth after it are full scans; the others are guided.
    assert!(in_regions >= FRAMES / 2, "{in_regions} guided frames");
    // --full-scan-every needs --guided, and 0 is refused.
    let (_, stderr, code) = track(
        &[&base[..], &["--full-scan-every", "3"]].concat(),
        &clip.dir,
        None,
    );
    assert_eq!(code, Some(2), "{stderr}");
    let (_, stderr, code) = track(
        &[&base[..], &["--guided", "--full-scan-every", "0"]].concat(),
        &clip.dir,
        None,
    );
    assert_eq!(code, Some(2), "{stderr}");
}

/// The clip tracked as it is and with `extra` options (both must succeed), as JSON lines,
/// one per frame each.
fn plain_and_told(dir: &Path, extra: &[&str]) -> (Vec<serde_json::Value>, Vec<serde_json::Value>) {
    let base = common::CLIP_ARGS;
    let (plain, stderr, code) = track(&base, dir, None);
    assert_eq!(code, Some(0), "{stderr}");
    let mut args = base.to_vec();
    args.extend(extra);
    let (told, stderr, code) = track(&args, dir, None);
    assert_eq!(code, Some(0), "{stderr}");
    let (plain, told) = (lines(&plain), lines(&told));
    assert_eq!(plain.len(), told.len());
    (plain, told)
}

/// #30: `--controller FILE` tells the tracker the follower's own controller (the reference
/// scenario's, holding the start), which changes the leader's filter; a bad file is one
/// error line naming the field.
#[test]
fn the_follower_controller_is_told_from_a_file() {
    let clip = common::reference_clip("controller", FRAMES);
    std::fs::write(
        clip.dir.join("controller.yaml"),
        "leader: 1\nl12_desired: 1.0307764064044151\nalpha12_desired: 0.24497866312686414\n\
         k_l: 1.0\nk_alpha: 1.0\n",
    )
    .unwrap();
    let (plain, told) = plain_and_told(&clip.dir, &["--controller", "controller.yaml"]);
    let base = common::CLIP_ARGS;
    let v1 = |f: &serde_json::Value| f["leaders"][0]["v1"].as_f64().unwrap();
    let last = (plain.last().unwrap(), told.last().unwrap());
    assert!(v1(last.1).is_finite());
    assert_ne!(v1(last.0), v1(last.1), "the controller changed nothing");
    std::fs::write(
        clip.dir.join("bad.yaml"),
        "leader: 1\nl12_desired: 1.0\nalpha12_desired: 0.2\nk_l: -1.0\nk_alpha: 1.0\n",
    )
    .unwrap();
    let mut args = base.to_vec();
    args.extend(["--controller", "bad.yaml"]);
    let (_, stderr, code) = track(&args, &clip.dir, None);
    assert_eq!(code, Some(1), "{stderr}");
    let errors: Vec<&str> = stderr.lines().filter(|l| l.contains("error")).collect();
    assert_eq!(errors.len(), 1, "{stderr}");
    assert!(
        errors[0].contains("controller file bad.yaml") && errors[0].contains("k_l"),
        "{stderr}"
    );
    let _ = std::fs::remove_dir_all(&clip.dir);
}

/// #30: `--odometry-noise` reaches the tracker: told that its inputs are noisy, it widens its
/// predictions, so the reported uncertainty grows and the estimates differ.
#[test]
fn the_odometry_noise_is_told_from_the_command_line() {
    let clip = common::reference_clip("odometry", FRAMES);
    let (plain, told) = plain_and_told(&clip.dir, &["--odometry-noise", "0.01,0.01"]);
    let std = |f: &serde_json::Value| f["leaders"][0]["l12_std"].as_f64().unwrap();
    let last = (plain.last().unwrap(), told.last().unwrap());
    assert!(
        std(last.1) > std(last.0),
        "l12 std {} told, {} not told",
        std(last.1),
        std(last.0)
    );
    let _ = std::fs::remove_dir_all(&clip.dir);
}
