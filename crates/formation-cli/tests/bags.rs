//! `track BAG`: the fixture bags written by Python's `mcap-ros2-support` and `rosbags`
//! (`cargo xtask bags`) reproduce the folder path's estimates; `--mcap` output reads back;
//! broken bags give one line naming the topic and the message, never a panic.
#![allow(clippy::unwrap_used)] // Tests may unwrap (house rules); helpers here are test code too.

mod common;

use std::path::{Path, PathBuf};

use formation_io::bag::cdr::{CdrWriter, mono8_image};
use formation_io::bag::mcap::McapReader;
use formation_io::mcap_out::McapWriter;

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/bags")
}

fn tmp(name: &str) -> PathBuf {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("bags-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn json_lines(stdout: &[u8]) -> Vec<serde_json::Value> {
    String::from_utf8_lossy(stdout)
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

fn stderr(out: &std::process::Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

fn expected(name: &str) -> Vec<serde_json::Value> {
    json_lines(&std::fs::read(fixtures().join(name)).unwrap())
}

#[test]
fn the_demo_bags_reproduce_the_folder_path() {
    let dir = tmp("demo");
    let want = expected("demo.expected.jsonl");
    // The leader is tracked in these frames, so the comparison is not of empty lists.
    assert!(
        want.iter()
            .any(|l| !l["leaders"].as_array().unwrap().is_empty())
    );
    for (bag, frames) in [("demo_zstd.mcap", want.len()), ("demo_lz4.mcap", 2)] {
        let out_mcap = dir.join(format!("{bag}.out.mcap"));
        let out = common::run(
            &dir,
            &[
                "--quiet",
                "track",
                fixtures().join(bag).to_str().unwrap(),
                "--json",
                "--mcap",
                out_mcap.to_str().unwrap(),
            ],
        );
        assert_eq!(out.status.code(), Some(0), "{bag}: {}", stderr(&out));
        let got = json_lines(&out.stdout);
        common::same_estimates(&got, &want[..frames]);
        // Every line names its message and stamp.
        assert_eq!(got[1]["message"], 1);
        assert_eq!(got[0]["missing_before"], 0);
        assert!(got[1]["stamp_ns"].as_u64().unwrap() > got[0]["stamp_ns"].as_u64().unwrap());
        // The output reads back with our reader: one message per channel per frame, and
        // the estimate channel says what the JSON lines say.
        let mut r = McapReader::open(&out_mcap).unwrap();
        let summary = r.summary().unwrap().expect("a summary");
        assert_eq!(summary.channels.len(), 4);
        let mut counts = std::collections::BTreeMap::<String, usize>::new();
        let mut estimates = Vec::new();
        while let Some(m) = r.next_message().unwrap() {
            let id = m.channel_id;
            let data = m.data.to_vec();
            let topic = r.channels()[&id].topic.clone();
            *counts.entry(topic.clone()).or_default() += 1;
            if topic == "/formation/estimate" {
                estimates.push(serde_json::from_slice::<serde_json::Value>(&data).unwrap());
            } else if topic != "/camera/image" {
                serde_json::from_slice::<serde_json::Value>(&data).unwrap();
            }
        }
        assert!(counts.values().all(|n| *n == frames), "{counts:?}");
        for (e, l) in estimates.iter().zip(&got) {
            let el = e["leaders"].as_array().unwrap();
            let ll = l["leaders"].as_array().unwrap();
            assert_eq!(el.len(), ll.len());
            for (a, b) in el.iter().zip(ll) {
                assert_eq!(a["l12"], b["l12"]);
                let s = a["std"][0].as_f64().unwrap();
                let var = a["covariance"][0].as_f64().unwrap();
                assert!((var - s * s).abs() <= 1e-15 * var.abs(), "{var} vs {s}^2");
                // The MCAP's covariance (row-major, 25 numbers) is the JSON line's 5 x 5 one:
                // the formation block in full, and the formation-velocity terms.
                let flat: Vec<f64> = b["covariance"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .flat_map(|row| row.as_array().unwrap().iter().map(|v| v.as_f64().unwrap()))
                    .collect();
                let mcap: Vec<f64> = a["covariance"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|v| v.as_f64().unwrap())
                    .collect();
                assert_eq!(mcap, flat);
                // The IMM (the tracker's default) estimates formation and velocities jointly:
                // the l12-v1 term is its own, the same both ways.
                assert_eq!(mcap[3], mcap[15], "l12-v1 term symmetric");
                assert_eq!(mcap[1], mcap[5], "symmetric");
            }
        }
    }
}

#[test]
fn the_duckietown_rosbag2_folder_is_read_and_calibrated_from_camera_info() {
    let dir = tmp("duckietown");
    let out = common::run(
        &dir,
        &[
            "--quiet",
            "track",
            fixtures().join("duckietown").to_str().unwrap(),
            "--json",
            "--fps",
            "10",
        ],
    );
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("calibration from /camera/camera_info (640x480)"),
        "{}",
        stderr(&out)
    );
    // tag36h11 is not read by this build: the folder path finds nothing either, and the
    // comparison checks frames, sources of time and marker counts.
    common::same_estimates(
        &json_lines(&out.stdout),
        &expected("duckietown.expected.jsonl"),
    );
}

/// A bag of `frames` (stamp in ns, grey level) of 64x48 `mono8` images on `/cam/image`,
/// with optional CameraInfo `k` on `/cam/camera_info`; `encoding` and `message_encoding`
/// may be wrong on purpose.
fn synthetic_bag(
    path: &Path,
    frames: &[(u64, u8)],
    k: Option<[f64; 9]>,
    encoding: &str,
    message_encoding: &str,
) {
    let file = std::fs::File::create(path).unwrap();
    let mut w = McapWriter::new(file, "ros2").unwrap();
    let s = w
        .add_schema("sensor_msgs/msg/Image", "ros2msg", b"")
        .unwrap();
    let img = w.add_channel(s, "/cam/image", message_encoding).unwrap();
    let s = w
        .add_schema("sensor_msgs/msg/CameraInfo", "ros2msg", b"")
        .unwrap();
    let info = w.add_channel(s, "/cam/camera_info", "cdr").unwrap();
    for &(stamp, level) in frames {
        if let Some(k) = k {
            let mut c = CdrWriter::new();
            c.header(stamp, "cam");
            c.u32(48);
            c.u32(64);
            c.string("plumb_bob");
            c.u32(5);
            for _ in 0..5 {
                c.f64(0.0);
            }
            for v in k.iter().chain(&[1.0, 0., 0., 0., 1., 0., 0., 0., 1.]) {
                c.f64(*v);
            }
            for _ in 0..12 {
                c.f64(0.0);
            }
            w.write(info, stamp, &c.finish()).unwrap();
        }
        let mut data = mono8_image(stamp, "cam", 64, 48, &[level; 64 * 48]);
        if encoding != "mono8" {
            // Same length, another encoding name ("yuv422" has the length of "mono8" + 1,
            // so rebuild).
            let mut c = CdrWriter::new();
            c.header(stamp, "cam");
            c.u32(48);
            c.u32(64);
            c.string(encoding);
            c.u8(0);
            c.u32(64);
            c.bytes(&[level; 64 * 48]);
            data = c.finish();
        }
        w.write(img, stamp, &data).unwrap();
    }
    w.finish().unwrap();
}

const K64: [f64; 9] = [60.0, 0.0, 31.5, 0.0, 60.0, 23.5, 0.0, 0.0, 1.0];
const MS: u64 = 1_000_000;

fn track_bag(dir: &Path, bag: &Path, extra: &[&str]) -> std::process::Output {
    let mut args = vec!["--quiet", "track", bag.to_str().unwrap(), "--json"];
    args.extend_from_slice(extra);
    common::run(dir, &args)
}

/// One line on stderr, and no panic.
fn one_line_error(out: &std::process::Output) -> String {
    let e = stderr(out);
    assert!(!e.contains("panicked"), "{e}");
    let lines: Vec<&str> = e.lines().filter(|l| l.contains("error:")).collect();
    assert_eq!(lines.len(), 1, "{e}");
    lines[0].to_owned()
}

#[test]
fn irregular_stamps_are_put_in_order_and_counted() {
    let dir = tmp("irregular");
    let bag = dir.join("irregular.mcap");
    // Frames at 100 ms: 0, 1, 3, 2 (reordered), 4, 7 (2 missing), 7 again (repeated stamp:
    // dropped), 8..=18, then 5 (later than the window: dropped).
    let mut stamps: Vec<u64> = vec![0, 1, 3, 2, 4, 7, 7];
    stamps.extend(8..=18);
    stamps.push(5);
    let frames: Vec<(u64, u8)> = stamps
        .iter()
        .map(|s| (1_000 * MS + s * 100 * MS, 128))
        .collect();
    synthetic_bag(&bag, &frames, Some(K64), "mono8", "cdr");
    let out = track_bag(&dir, &bag, &[]);
    // Frames were dropped as out of order: partial (3).
    assert_eq!(out.status.code(), Some(3), "{}", stderr(&out));
    let lines = json_lines(&out.stdout);
    let got: Vec<u64> = lines
        .iter()
        .map(|l| (l["stamp_ns"].as_u64().unwrap() - 1_000 * MS) / (100 * MS))
        .collect();
    let want: Vec<u64> = [0, 1, 2, 3, 4, 7].into_iter().chain(8..=18).collect();
    assert_eq!(got, want);
    assert_eq!(lines[5]["missing_before"], 2);
    // t is the stamp's offset from the first frame.
    assert!((lines[5]["t"].as_f64().unwrap() - 0.7).abs() < 1e-9);
    let e = stderr(&out);
    assert!(
        e.contains("1 reordered, 2 out of order (dropped), 2 missing"),
        "{e}"
    );
}

#[test]
fn bad_bags_give_one_line_naming_the_topic_and_message() {
    let dir = tmp("bad");
    let frames: Vec<(u64, u8)> = (0..5).map(|i| (1_000 * MS + i * 33 * MS, 100)).collect();

    // A message encoding we do not read.
    let bag = dir.join("json.mcap");
    synthetic_bag(&bag, &frames, Some(K64), "mono8", "json");
    let out = track_bag(&dir, &bag, &[]);
    assert_eq!(out.status.code(), Some(1));
    let e = one_line_error(&out);
    assert!(
        e.contains("topic /cam/image, message 0: message encoding `json`"),
        "{e}"
    );

    // An image encoding we do not read.
    let bag = dir.join("yuv.mcap");
    synthetic_bag(&bag, &frames, Some(K64), "yuv422", "cdr");
    let out = track_bag(&dir, &bag, &[]);
    assert_eq!(out.status.code(), Some(1));
    let e = one_line_error(&out);
    assert!(
        e.contains("topic /cam/image, message 0: image encoding `yuv422`"),
        "{e}"
    );

    // A CameraInfo with a zero focal length.
    let bag = dir.join("zero-f.mcap");
    let mut k = K64;
    k[0] = 0.0;
    synthetic_bag(&bag, &frames, Some(k), "mono8", "cdr");
    let out = track_bag(&dir, &bag, &[]);
    assert_eq!(out.status.code(), Some(1));
    let e = one_line_error(&out);
    assert!(e.contains("topic /cam/camera_info, message 0:"), "{e}");
    assert!(e.contains("focal"), "{e}");

    // No CameraInfo at all.
    let bag = dir.join("no-info.mcap");
    synthetic_bag(&bag, &frames, None, "mono8", "cdr");
    let out = track_bag(&dir, &bag, &[]);
    assert_eq!(out.status.code(), Some(1));
    let e = one_line_error(&out);
    assert!(e.contains("CameraInfo") && e.contains("--camera"), "{e}");

    // A topic of the wrong type chosen as the image topic.
    let bag = dir.join("ok.mcap");
    synthetic_bag(&bag, &frames, Some(K64), "mono8", "cdr");
    let out = track_bag(&dir, &bag, &["--image-topic", "/cam/camera_info"]);
    assert_eq!(out.status.code(), Some(1));
    let e = one_line_error(&out);
    assert!(
        e.contains("topic /cam/camera_info, message 0: sensor_msgs/msg/CameraInfo is not an image"),
        "{e}"
    );
}

#[test]
fn mcap_output_works_for_image_folders_too_and_no_images_leaves_them_out() {
    let d = common::blank_frames("bags-folder-mcap");
    for (flags, channels) in [(&[][..], 4usize), (&["--no-images"][..], 3)] {
        let out_mcap = d.join("out.mcap");
        let mut args = vec![
            "--quiet",
            "track",
            "frames",
            "--camera",
            "camera.yaml",
            "--mcap",
            "out.mcap",
        ];
        args.extend_from_slice(flags);
        let out = common::run(&d, &args);
        assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
        let mut r = McapReader::open(&out_mcap).unwrap();
        assert_eq!(r.summary().unwrap().unwrap().channels.len(), channels);
        let mut times = Vec::new();
        while let Some(m) = r.next_message().unwrap() {
            times.push(m.log_time);
        }
        // One message per channel per frame, stamped t = frame / 30 s.
        assert_eq!(times.len(), 3 * channels);
        assert_eq!(*times.last().unwrap(), 66_666_667);
    }
}

#[test]
fn an_unreadable_odometry_message_keeps_the_previous_inputs_and_is_counted() {
    let dir = tmp("bad-odom");
    let bag = dir.join("bad-odom.mcap");
    let file = std::fs::File::create(&bag).unwrap();
    let mut w = McapWriter::new(file, "ros2").unwrap();
    let s = w
        .add_schema("sensor_msgs/msg/Image", "ros2msg", b"")
        .unwrap();
    let img = w.add_channel(s, "/cam/image", "cdr").unwrap();
    let s = w
        .add_schema("nav_msgs/msg/Odometry", "ros2msg", b"")
        .unwrap();
    let odom = w.add_channel(s, "/odom", "cdr").unwrap();
    for i in 0..3u64 {
        let t = 1_000 * MS + i * 100 * MS;
        // A CDR header and nothing else: too short for an Odometry.
        w.write(odom, t, &[0, 1, 0, 0, 7]).unwrap();
        w.write(img, t, &mono8_image(t, "cam", 64, 48, &[50; 64 * 48]))
            .unwrap();
    }
    w.finish().unwrap();
    let cam = dir.join("cam.yaml");
    std::fs::write(
        &cam,
        "image_width: 64\nimage_height: 48\ncamera_matrix:\n  rows: 3\n  cols: 3\n  data: [60.0, 0.0, 31.5, 0.0, 60.0, 23.5, 0.0, 0.0, 1.0]\ndistortion_model: plumb_bob\ndistortion_coefficients:\n  rows: 1\n  cols: 5\n  data: [0.0, 0.0, 0.0, 0.0, 0.0]\n",
    )
    .unwrap();
    let out = track_bag(&dir, &bag, &["--camera", cam.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(3), "{}", stderr(&out));
    assert_eq!(json_lines(&out.stdout).len(), 3);
    let e = stderr(&out);
    assert!(
        e.contains("track: topic /odom, message 0: needs 4 bytes"),
        "{e}"
    );
    assert!(e.contains("3 frames tracked, 0 broken"), "{e}");
    assert!(e.contains("3 unreadable input messages"), "{e}");
}

#[test]
fn several_image_topics_need_a_choice_and_the_error_lists_them() {
    let dir = tmp("several");
    let bag = dir.join("two-cameras.mcap");
    let file = std::fs::File::create(&bag).unwrap();
    let mut w = McapWriter::new(file, "ros2").unwrap();
    let s = w
        .add_schema("sensor_msgs/msg/Image", "ros2msg", b"")
        .unwrap();
    let left = w.add_channel(s, "/left/image", "cdr").unwrap();
    let right = w.add_channel(s, "/right/image", "cdr").unwrap();
    for c in [left, right] {
        w.write(c, 1, &mono8_image(1, "cam", 64, 48, &[9; 64 * 48]))
            .unwrap();
    }
    w.finish().unwrap();
    let out = track_bag(&dir, &bag, &["--camera", "missing.yaml"]);
    assert_eq!(out.status.code(), Some(1));
    let e = one_line_error(&out);
    assert!(
        e.contains("several image topics, pick one with --image-topic: /left/image (sensor_msgs/msg/Image), /right/image"),
        "{e}"
    );
    let out = track_bag(&dir, &bag, &["--image-topic", "/middle/image"]);
    let e = one_line_error(&out);
    assert!(
        e.contains("--image-topic /middle/image: no such topic"),
        "{e}"
    );
}

/// The records of an MCAP file: (opcode, offset of the record).
fn records(bytes: &[u8]) -> Vec<(u8, usize)> {
    let mut out = Vec::new();
    let mut pos = 8;
    while pos + 9 <= bytes.len() {
        let op = bytes[pos];
        let len = u64::from_le_bytes(bytes[pos + 1..pos + 9].try_into().unwrap()) as usize;
        out.push((op, pos));
        if op == 0x02 {
            break;
        }
        pos += 9 + len;
    }
    out
}

#[test]
fn a_truncated_or_corrupt_bag_keeps_the_frames_before_the_damage() {
    let dir = tmp("corrupt");
    let bytes = std::fs::read(fixtures().join("demo_zstd.mcap")).unwrap();
    let chunks: Vec<usize> = records(&bytes)
        .into_iter()
        .filter(|(op, _)| *op == 0x06)
        .map(|(_, at)| at)
        .collect();
    assert!(chunks.len() >= 3, "{} chunks", chunks.len());

    // Cut inside the third chunk.
    let bag = dir.join("truncated.mcap");
    std::fs::write(&bag, &bytes[..chunks[2] + 100]).unwrap();
    let out = track_bag(&dir, &bag, &[]);
    assert_eq!(out.status.code(), Some(3), "{}", stderr(&out));
    let lines = json_lines(&out.stdout);
    assert!(!lines.is_empty());
    let e = stderr(&out);
    assert!(!e.contains("panicked"), "{e}");
    assert!(e.contains("truncated"), "{e}");
    assert!(e.contains("after message"), "{e}");
    assert!(e.contains("of /camera/image_raw"), "{e}");
    let warning: Vec<&str> = e.lines().filter(|l| l.contains("warning:")).collect();
    assert_eq!(warning.len(), 1, "{e}");

    // Flip a byte of the third chunk's CRC (after its start and end times and size).
    let bag = dir.join("crc.mcap");
    let mut bad = bytes.clone();
    bad[chunks[2] + 9 + 24] ^= 0x5a;
    std::fs::write(&bag, &bad).unwrap();
    let out = track_bag(&dir, &bag, &[]);
    assert_eq!(out.status.code(), Some(3), "{}", stderr(&out));
    let e = stderr(&out);
    assert!(e.contains("is corrupt (CRC"), "{e}");
    let before = json_lines(&out.stdout);
    assert!(!before.is_empty());
    // The frames before the damage are the good bag's.
    let want = expected("demo.expected.jsonl");
    common::same_estimates(&before, &want[..before.len()]);
}
