//! The ROS 2 node across processes over DDS: `ros2-sim` publishes a recording, `ros2`
//! tracks it live. Every test opens its sockets only inside a private network namespace it
//! makes (`unshare -rn`, loopback up): no packet can leave the machine.
#![allow(clippy::unwrap_used)] // tests may unwrap (house rules)

mod common;

use std::path::Path;
use std::process::{Command, Output};

use common::{CLIP_ARGS, reference_clip};

const BIN: &str = env!("CARGO_BIN_EXE_formation-tracker");

/// One namespace test at a time: each runs a node against a 30 Hz publisher and counts
/// dropped frames, which other tests' rendering on the same two cores must not cause.
static ONE_AT_A_TIME: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn one_at_a_time() -> std::sync::MutexGuard<'static, ()> {
    ONE_AT_A_TIME
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// `bash -c "SCRIPT"` (its arguments follow as `$0`, `$1`, ...) in a new user and network
/// namespace whose only interface is the loopback, up, with multicast routed to it; ROS 2
/// discovery kept on localhost, in `domain`.
fn namespace_command(script: &str, domain: &str) -> Command {
    let mut c = Command::new("unshare");
    c.args(["--user", "--map-root-user", "--net", "bash", "-c"])
        .arg(format!(
            "set -e; ip link set lo up; ip link set lo multicast on; \
             ip route add 224.0.0.0/4 dev lo; {script}"
        ))
        .env("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
        .env("ROS_DOMAIN_ID", domain);
    c
}

/// Runs `script` in a private network namespace ([`namespace_command`]), in `dir`, with the
/// binary as `$BIN`.
fn in_namespace(script: &str, dir: &Path) -> Output {
    let out = namespace_command(script, "17")
        .env("BIN", BIN)
        .current_dir(dir)
        .output()
        .expect("`unshare` (util-linux) runs these tests in a private network namespace");
    assert!(
        out.status.success(),
        "namespace script failed ({}): {}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

fn json_lines(text: &str) -> Vec<serde_json::Value> {
    text.lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

/// Done-when of #34: given a recording published at 30 Hz, the node's estimates equal
/// `track`'s on the same frames to 1e-9, no frame dropped.
#[test]
fn the_node_gives_what_track_gives() {
    let _serial = one_at_a_time();
    let frames = 45;
    let clip = reference_clip("ros2-node", frames);
    let track = Command::new(BIN)
        .arg("track")
        .args(CLIP_ARGS)
        .current_dir(&clip.dir)
        .output()
        .unwrap();
    assert!(
        track.status.success(),
        "{}",
        String::from_utf8_lossy(&track.stderr)
    );
    let want = json_lines(&String::from_utf8_lossy(&track.stdout));
    assert_eq!(want.len(), frames);

    let out = in_namespace(
        &format!(
            "\"$BIN\" ros2 --json --max-frames {frames} > node.jsonl 2> node.err & node=$!; \
             \"$BIN\" ros2-sim --replay . --fps 30 2> sim.err; \
             wait $node; cat node.err sim.err >&2"
        ),
        &clip.dir,
    );
    let stderr = String::from_utf8_lossy(&out.stderr).to_string();
    assert!(
        stderr.contains(&format!(
            "{frames} frames tracked of {frames} received; 0 dropped"
        )),
        "{stderr}"
    );
    assert!(stderr.contains("0 unusable"), "{stderr}");
    let got = json_lines(&std::fs::read_to_string(clip.dir.join("node.jsonl")).unwrap());
    assert_eq!(got.len(), frames, "{stderr}");
    let compared = common::same_estimates(&got, &want);
    // The leader is tracked through the clip: the comparison is not vacuous.
    assert!(
        compared >= frames - 2,
        "{compared} leader estimates compared"
    );
    let _ = std::fs::remove_dir_all(&clip.dir);
}

/// Runs the ignored test `name` of this binary inside a private network namespace.
fn this_test_in_namespace(name: &str) {
    let exe = std::env::current_exe().unwrap();
    let out = namespace_command(
        "exec \"$0\" --exact \"$1\" --include-ignored --nocapture",
        "18",
    )
    .arg(exe)
    .arg(name)
    .output()
    .expect("`unshare` (util-linux) runs these tests in a private network namespace");
    let text = format!(
        "{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(out.status.success(), "{text}");
    assert!(
        text.contains("1 passed"),
        "the inner test did not run: {text}"
    );
}

/// Done-when of #34: bad input (a malformed image, `camera_info` with zeros, a NaN in
/// odometry, a frame before any calibration, a stamp going back) logs one clear line each
/// and the node goes on, tracks the good frames, and stops cleanly on SIGINT.
#[test]
fn the_node_reports_bad_input_and_goes_on() {
    let _serial = one_at_a_time();
    this_test_in_namespace("bad_input_inside_a_namespace");
}

#[test]
#[ignore = "runs inside a private network namespace, from the_node_reports_bad_input_and_goes_on"]
fn bad_input_inside_a_namespace() {
    use formation_ros2::msg::{self, Bytes, F64Array, Header, Time};
    use formation_ros2::topics::{publisher, reliable};
    use std::process::Stdio;
    use std::time::{Duration, Instant};

    let mut child = Command::new(BIN)
        .args(["ros2", "--json"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let stdout = common::lines_of(child.stdout.take().unwrap());
    let stderr = common::lines_of(child.stderr.take().unwrap());
    let mut node = formation_ros2::RosEnv::from_env()
        .unwrap()
        .node("/", "bad_publisher")
        .unwrap();
    let q = reliable(50);
    let images = publisher::<msg::Image>(&mut node, "image_raw", &q).unwrap();
    let infos = publisher::<msg::CameraInfo>(&mut node, "camera_info", &q).unwrap();
    let odom = publisher::<msg::Odometry>(&mut node, "odom", &q).unwrap();
    let deadline = Instant::now() + Duration::from_secs(20);
    while images.get_subscription_count(&node) == 0
        || infos.get_subscription_count(&node) == 0
        || odom.get_subscription_count(&node) == 0
    {
        assert!(
            Instant::now() < deadline,
            "the node's readers never matched"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    std::thread::sleep(Duration::from_millis(500));
    let base = 1_700_000_000_000_000_000u64;
    let header = |k: u64| Header {
        stamp: Time::from_ns(base + k * 33_333_333),
        frame_id: "camera".into(),
    };
    let image = |k: u64, width: u32, step: u32, len: usize, encoding: &str| msg::Image {
        header: header(k),
        height: 480,
        width,
        encoding: encoding.into(),
        is_bigendian: 0,
        step,
        data: Bytes(vec![128; len]),
    };
    let good = |k: u64| image(k, 640, 640, 640 * 480, "mono8");
    let pause = || std::thread::sleep(Duration::from_millis(120));
    // A frame before any calibration.
    images.publish(good(0)).unwrap();
    pause();
    // CameraInfo with zeros.
    infos
        .publish(msg::CameraInfo {
            header: header(1),
            height: 480,
            width: 640,
            ..msg::CameraInfo::default()
        })
        .unwrap();
    pause();
    // A NaN in odometry.
    let mut o = msg::Odometry {
        header: header(1),
        ..msg::Odometry::default()
    };
    o.twist.twist.linear.x = f64::NAN;
    odom.publish(o).unwrap();
    pause();
    // The good calibration, then a malformed image and an unknown encoding.
    let k = F64Array([554.25, 0.0, 319.5, 0.0, 554.25, 239.5, 0.0, 0.0, 1.0]);
    infos
        .publish(msg::CameraInfo {
            header: header(2),
            height: 480,
            width: 640,
            distortion_model: "plumb_bob".into(),
            d: vec![0.0; 5],
            k,
            ..msg::CameraInfo::default()
        })
        .unwrap();
    pause();
    images.publish(image(3, 640, 640, 1000, "mono8")).unwrap();
    pause();
    images
        .publish(image(4, 640, 640, 640 * 480, "yuv_weird"))
        .unwrap();
    pause();
    // Five good frames, then one whose stamp goes back.
    for k in 5..10 {
        images.publish(good(k)).unwrap();
        pause();
    }
    images.publish(good(7)).unwrap();
    pause();
    let wait_for = |rx: &std::sync::mpsc::Receiver<String>, what: &str| -> String {
        let deadline = Instant::now() + Duration::from_secs(10);
        let mut seen = Vec::new();
        while Instant::now() < deadline {
            if let Ok(line) = rx.recv_timeout(Duration::from_millis(100)) {
                if line.contains(what) {
                    return line;
                }
                seen.push(line);
            }
        }
        panic!("no line with {what:?}; got: {seen:#?}");
    };
    let mut tracked = 0;
    while tracked < 5 {
        let line = stdout
            .recv_timeout(Duration::from_secs(10))
            .expect("five good frames tracked");
        assert!(line.starts_with('{'), "{line}");
        tracked += 1;
    }
    std::thread::sleep(Duration::from_millis(300));
    let status = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success());
    let code = child.wait().unwrap();
    // Every problem in one clear line, in the order it happened, and the summary.
    let before_calibration = wait_for(&stderr, "before any CameraInfo");
    assert!(
        before_calibration.starts_with("ros2: "),
        "{before_calibration}"
    );
    let zeros = wait_for(&stderr, "CameraInfo");
    assert!(
        zeros.contains("camera_matrix") && zeros.contains("alpha 0"),
        "{zeros}"
    );
    let nan = wait_for(&stderr, "not finite");
    assert!(nan.contains("twist.linear.x"), "{nan}");
    let short = wait_for(&stderr, "frame ");
    assert!(short.contains("Image"), "{short}");
    let weird = wait_for(&stderr, "yuv_weird");
    assert!(weird.contains("Image"), "{weird}");
    let back = wait_for(&stderr, "not after the previous frame");
    assert!(back.contains("dropped"), "{back}");
    let summary = wait_for(&stderr, "frames tracked of");
    assert!(
        summary.contains("5 frames tracked of 9 received"),
        "{summary}"
    );
    assert!(
        summary.contains("4 unusable, 1 unusable inputs"),
        "{summary}"
    );
    assert!(code.success(), "SIGINT is how a node stops: exit {code}");
    assert!(stdout.try_recv().is_err(), "more frames tracked than sent");
}

/// Done-when of #34: the loop closed across processes. `ros2-sim` simulates the robot pair
/// and moves its follower by the `cmd_vel` that `ros2 --control` publishes from its tracked
/// estimate. The leader is hidden from 2 s to 5 s: the follower holds the formation before,
/// stops once the leader has been unseen for --stop-after (2 s, the documented default), and
/// drives again once the leader is back.
#[test]
fn closed_loop_across_processes_holds_the_formation_and_stops_when_the_leader_is_hidden() {
    let _serial = one_at_a_time();
    let dir = std::env::temp_dir().join(format!("ft-ros2-loop-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let reference =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/scenarios/reference.yaml");
    let scenario = std::fs::read_to_string(reference)
        .unwrap()
        .replace("duration: 8.0", "duration: 6.5")
        + "vision:\n  render: {supersampling: 2}\n  occlusions: [{from: 2.0, to: 5.0}]\n";
    std::fs::write(dir.join("scenario.yaml"), scenario).unwrap();
    let out = in_namespace(
        "\"$BIN\" ros2-sim --scenario scenario.yaml --write-controller controller.yaml 2> /dev/null; \
         \"$BIN\" ros2 -q --control controller.yaml > /dev/null 2> node.err & node=$!; \
         \"$BIN\" ros2-sim -q --scenario scenario.yaml --truth truth.csv 2> sim.err; \
         kill -INT $node; wait $node; cat node.err sim.err >&2",
        &dir,
    );
    let stderr = String::from_utf8_lossy(&out.stderr).to_string();
    assert!(stderr.contains("196 answered by a command"), "{stderr}");
    let text = std::fs::read_to_string(dir.join("truth.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let rows: Vec<Vec<f64>> = lines
        .map(|l| {
            l.split(',')
                .map(|v| match v {
                    "true" => 1.0,
                    "false" => 0.0,
                    v => v.parse().unwrap(),
                })
                .collect()
        })
        .collect();
    assert_eq!(rows.len(), 196);
    let (t, v, l12, l12d) = (col("t"), col("v2_command"), col("l12"), col("l12_desired"));
    let (alpha, alphad) = (col("alpha12"), col("alpha12_desired"));
    for r in &rows {
        let moving = r[v].abs() > 1e-9;
        if r[t] > 0.5 && r[t] < 2.0 {
            // Holding the formation on the tracked estimate.
            assert!(moving, "t = {}: stopped while the leader is seen", r[t]);
            assert!(
                (r[l12] - r[l12d]).abs() < 0.05,
                "t = {}: l12 {} vs {}",
                r[t],
                r[l12],
                r[l12d]
            );
            assert!(
                (r[alpha] - r[alphad]).abs() < 0.05,
                "t = {}: alpha12 {}",
                r[t],
                r[alpha]
            );
        }
        if r[t] > 2.0 + 2.0 + 0.1 && r[t] < 5.0 {
            assert!(
                !moving,
                "t = {}: still driving, the leader unseen for {} s",
                r[t],
                r[t] - 2.0
            );
        }
        if r[t] > 5.3 {
            assert!(
                moving,
                "t = {}: not driving again after the leader came back",
                r[t]
            );
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Regression (found by `cargo xtask ros2-interop`): a subscriber gets every message the node
/// publishes, the first of a leader's (its writers used to be made on first sight, and DDS
/// matched them only after that first write) and the last frame's (the node used to exit
/// before sending them). The readers are best effort, as `ros2 topic echo`'s default: a
/// reliable RustDDS reader in this test got nothing in about half the runs (CycloneDDS's
/// reliable readers get everything: `cargo xtask ros2-interop`), see docs/ros2.md.
#[test]
fn a_subscriber_gets_every_message_the_node_publishes() {
    let _serial = one_at_a_time();
    this_test_in_namespace("every_message_inside_a_namespace");
}

#[test]
#[ignore = "runs inside a private network namespace, from a_subscriber_gets_every_message_the_node_publishes"]
fn every_message_inside_a_namespace() {
    use formation_ros2::msg;
    use formation_ros2::topics::{sensor_data, subscription};
    use std::time::{Duration, Instant};

    let frames = 30;
    let clip = reference_clip("ros2-every", frames);
    // The node runs first and a subscriber joins it, as `ros2 topic echo` would.
    let tracker = Command::new(BIN)
        .args(["ros2", "-q", "--json", "--max-frames", &frames.to_string()])
        .current_dir(&clip.dir)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(500));
    let mut node = formation_ros2::RosEnv::from_env()
        .unwrap()
        .node("/", "listener")
        .unwrap();
    let formation = subscription::<msg::Float64MultiArray>(
        &mut node,
        "formation/leader_1/formation",
        &sensor_data(100),
    )
    .unwrap();
    let tf = subscription::<msg::TfMessage>(&mut node, "/tf", &sensor_data(100)).unwrap();
    // The node's writers must know this reader before the first frame (discovery between
    // two participants can take a while when one started first).
    let deadline = Instant::now() + Duration::from_secs(20);
    while formation.get_publisher_count(&node) == 0 || tf.get_publisher_count(&node) == 0 {
        assert!(
            Instant::now() < deadline,
            "the node's writers never matched"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    // Matched here; the writers' side may learn of this reader a moment later.
    std::thread::sleep(Duration::from_millis(500));
    let sim = Command::new(BIN)
        .args(["ros2-sim", "--replay", "."])
        .current_dir(&clip.dir)
        .output()
        .unwrap();
    assert!(
        sim.status.success(),
        "{}",
        String::from_utf8_lossy(&sim.stderr)
    );
    let out = tracker.wait_with_output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let lines = String::from_utf8_lossy(&out.stdout).to_string();
    // The frames in which the node had a leader 1 to publish.
    let with_leader = lines.lines().filter(|l| l.contains("\"robot\":1")).count();
    assert!(with_leader >= frames - 2, "{lines}");
    let (mut got_formation, mut got_tf) = (0, 0);
    let deadline = Instant::now() + Duration::from_secs(5);
    while Instant::now() < deadline && (got_formation < with_leader || got_tf < with_leader) {
        while let Ok(Some(_)) = formation.take() {
            got_formation += 1;
        }
        while let Ok(Some(_)) = tf.take() {
            got_tf += 1;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    assert_eq!(
        got_formation, with_leader,
        "formation messages received of published"
    );
    assert_eq!(got_tf, with_leader, "/tf messages received of published");
    let _ = std::fs::remove_dir_all(&clip.dir);
}
