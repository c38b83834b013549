//! The ROS 2 node across processes over DDS: `ros2-sim` publishes a recording, `ros2`
//! tracks it live. Every test opens its sockets only inside a private network namespace it
//! makes (`unshare -rn`, loopback up): no packet can leave the machine.
#![allow(clippy::unwrap_used)] // tests may unwrap (house rules)

mod common;

use std::path::Path;
use std::process::{Command, Output};

use common::{CLIP_ARGS, reference_clip};

const BIN: &str = env!("CARGO_BIN_EXE_formation-tracker");

/// Runs `script` (bash) in a new user and network namespace whose only interface is the
/// loopback, up, with multicast routed to it; ROS 2 discovery kept on localhost.
fn in_namespace(script: &str, dir: &Path) -> Output {
    let setup = "set -e; ip link set lo up; ip link set lo multicast on; \
                 ip route add 224.0.0.0/4 dev lo; export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST; \
                 export ROS_DOMAIN_ID=17;";
    let out = Command::new("unshare")
        .args(["--user", "--map-root-user", "--net", "bash", "-c"])
        .arg(format!("{setup} {script}"))
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
    let mut compared = 0;
    for (g, w) in got.iter().zip(&want) {
        assert_eq!(g["frame"], w["frame"]);
        let (gl, wl) = (
            g["leaders"].as_array().unwrap(),
            w["leaders"].as_array().unwrap(),
        );
        assert_eq!(gl.len(), wl.len(), "frame {}", w["frame"]);
        for (a, b) in gl.iter().zip(wl) {
            assert_eq!(a["robot"], b["robot"]);
            assert_eq!(a["status"], b["status"], "frame {}", w["frame"]);
            for k in ["l12", "alpha12", "beta12", "v1", "w1", "l12_std", "w1_std"] {
                let (x, y) = (a[k].as_f64().unwrap(), b[k].as_f64().unwrap());
                assert!(
                    (x - y).abs() <= 1e-9,
                    "frame {} {k}: node {x}, track {y}",
                    w["frame"]
                );
                compared += 1;
            }
        }
    }
    // The leader is tracked through the clip: the comparison is not vacuous.
    assert!(compared >= 7 * (frames - 2), "{compared} values compared");
    let _ = std::fs::remove_dir_all(&clip.dir);
}
