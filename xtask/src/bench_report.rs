//! `cargo xtask bench-report [--no-run] [--quick]`: run every criterion benchmark of the
//! workspace and write `docs/performance.md` from criterion's own estimates.
//!
//! The table is the only place benchmark figures are written down; it is regenerated, never
//! edited by hand. Each row gives the median time with its 95 % confidence interval (as
//! criterion computed it), the target from the issue that set it, and the machine it was
//! measured on.

use std::fmt::Write as _;
use std::path::Path;
use std::process::Command;

use serde_json::Value;

use crate::Result;

/// A benchmark with a target or a reference figure worth printing beside it.
struct Target {
    id: &'static str,
    /// Target in nanoseconds, if the issue set one.
    target_ns: Option<f64>,
    /// What the figure should be compared with.
    note: &'static str,
}

const TARGETS: &[Target] = &[
    Target {
        id: "dukf/ukf_step_6x3",
        target_ns: None,
        note: "one predict + update, 6 states, 3 measurements",
    },
    Target {
        id: "dukf/dual_step_6_2x3",
        target_ns: Some(3_000.0),
        note: "target <= 3 us, no heap allocation",
    },
    Target {
        id: "pose/one_face_4pts",
        target_ns: Some(5_000.0),
        note: "target <= 5 us; OpenCV solvePnP IPPE_SQUARE 9.5 us",
    },
    Target {
        id: "pose/three_faces_12pts_lm",
        target_ns: Some(20_000.0),
        note: "target <= 20 us; OpenCV solvePnP ITERATIVE 60 us",
    },
    Target {
        id: "fiducial/detect_640x480",
        target_ns: Some(1_000_000.0),
        note: "eight markers of 20-120 px (the accuracy scene); target <= 1.0 ms. #12 sets its \
               0.35 ms on the demo scene (`formation-sim/detect_full_640x480`); this scene took \
               0.56 ms when #12 was written, before the occlusion checks (#16) and the pattern \
               refinement (#13), whose costs the ratios below bound; OpenCV ArUco 3.1 ms, \
               AprilTag 3 8.5 ms",
    },
    Target {
        id: "formation-sim/detect_full_640x480",
        target_ns: Some(350_000.0),
        note: "demo scene, full frame; target <= 0.35 ms (#12)",
    },
    Target {
        id: "formation-sim/detect_guided_640x480",
        target_ns: None,
        note: "demo scene, the leader's predicted region only (#12)",
    },
    Target {
        id: "formation-sim/detect_full_3840x2160",
        target_ns: Some(6_000_000.0),
        note: "demo scene at 4K, full frame at full resolution; target <= 6 ms (#12)",
    },
    Target {
        id: "formation-sim/detect_coarse2_3840x2160",
        target_ns: None,
        note: "demo scene at 4K, full frame at half resolution, corners refined at full (#12)",
    },
    Target {
        id: "formation-sim/detect_guided_3840x2160",
        target_ns: Some(1_000_000.0),
        note: "demo scene at 4K, the leader's predicted region only; target <= 1.0 ms (#12)",
    },
    Target {
        id: "fiducial/detect_1920x1080",
        target_ns: Some(4_000_000.0),
        note: "target <= 4 ms; OpenCV ArUco 14.1 ms, AprilTag 3 78 ms",
    },
    Target {
        id: "fiducial/detect_1920x1080_rayon",
        target_ns: None,
        note: "a parallel search (`Search::in_parallel`) on rayon's pool (2 cores), the \
               frame as one job: binarization in bands (one pass each), components handed \
               out one at a time, largest first, each quad decoded where it is found; see \
               the ratio below (#12)",
    },
    Target {
        id: "formation-tracker/frame_pipeline_640x480",
        target_ns: Some(2_000_000.0),
        note: "detect + pose + track on one core, rendering excluded; target >= 500 frames/s",
    },
    Target {
        id: "formation-tracker/tracker_step",
        target_ns: None,
        note: "tracker update, one leader, measurement given",
    },
    Target {
        id: "synthcam/render_640x480_ss4",
        target_ns: Some(50_000_000.0),
        note: "target <= 50 ms on 2 cores",
    },
];

/// Ratios of two benchmarks of the same run that an issue bounds.
const RATIOS: &[(&str, &str, f64, &str)] = &[
    (
        "fiducial/detect_640x480_noisy",
        "fiducial/detect_640x480_clean",
        1.5,
        "noisy scene (sigma 10) vs the same scene clean",
    ),
    (
        "fiducial/detect_640x480",
        "fiducial/detect_640x480_no_side_check",
        1.2,
        "the default detector vs the same without the occlusion checks (`DetectorConfig::side_check`, #16): \
         they may cost a fifth of the frame at most",
    ),
    (
        "fiducial/detect_clutter_640x480",
        "fiducial/detect_640x480",
        1.5,
        "a marker-free clutter frame (black-bordered squares of every grid size) vs the marker \
         scene (#12): clutter may cost half a marker scene again at most. It was 1.04 on 11-23 \
         (701 us against 672 us) and 7.2 on 11-24, when the motion-blurred second reading of \
         marker-like quads (#16) came in",
    ),
    (
        "fiducial/detect_640x480_tag36h11",
        "fiducial/detect_640x480",
        1.2,
        "eight tag36h11 markers (587 codes, sorted-table lookup) vs eight of our own in the same \
         placements (#13): within 1.2x",
    ),
    (
        "fiducial/detect_640x480",
        "fiducial/detect_640x480_no_pattern",
        1.5,
        "the default detector vs the same without the corner refinement against the decoded \
         pattern (`RefineConfig::with_pattern`, #13), which halves the corner error of 20-40 px \
         markers: it may cost half the frame at most",
    ),
    (
        "cli/bag_read_16_frames",
        "cli/pipeline_16_frames",
        0.10,
        "reading 16 demo frames from an uncompressed ROS 2 bag vs the pipeline on them (#10)",
    ),
    (
        "formation-sim/detect_guided_3840x2160",
        "formation-sim/detect_full_3840x2160",
        1.0 / 6.0,
        "guided vs full-frame detection at 4K: the 1.0 ms and 6 ms targets' ratio (#12)",
    ),
    (
        "fiducial/detect_1920x1080_rayon",
        "fiducial/detect_1920x1080",
        1.0 / 1.6,
        "rayon on 2 cores vs one core at 1920x1080 (`Search::in_parallel`): speed-up \
         >= 1.6 (#12)",
    ),
];

pub fn run(args: &[String]) -> Result {
    let no_run = args.iter().any(|a| a == "--no-run");
    let quick = args.iter().any(|a| a == "--quick");
    let root = crate::workspace_root()?;
    if !no_run {
        let mut cmd = Command::new(env!("CARGO"));
        cmd.current_dir(&root)
            // Only the criterion bench targets: the libtest harness of the library targets
            // rejects criterion's options (`--quick` failed with "Unrecognized option").
            .args(["bench", "--workspace", "--exclude", "xtask", "--bench", "*"])
            // `fiducial/detect_1920x1080_rayon` runs on rayon's threads only with this.
            .args(["--features", "formation-fiducial/parallel", "--"]);
        if quick {
            cmd.args(["--warm-up-time", "1", "--measurement-time", "2"]);
        }
        let status = cmd.status()?;
        if !status.success() {
            return Err(format!("cargo bench failed with {status}").into());
        }
    }
    let criterion_dir = root.join("target").join("criterion");
    let mut rows = collect(&criterion_dir)?;
    if rows.is_empty() {
        return Err(format!(
            "no criterion results under {}; run without --no-run first",
            criterion_dir.display()
        )
        .into());
    }
    rows.sort_by(|a, b| a.id.cmp(&b.id));
    let mut doc = render(&rows, &machine());
    let out = root.join("docs").join("performance.md");
    // Sections measured by other harnesses (the ROS 2 node's latency) follow a marker line
    // and are kept as they are.
    if let Ok(old) = std::fs::read_to_string(&out)
        && let Some(at) = old.find(KEPT_MARKER)
    {
        doc.push('\n');
        doc.push_str(&old[at..]);
    }
    std::fs::write(&out, doc)?;
    println!(
        "bench-report: wrote {} ({} benchmarks)",
        out.display(),
        rows.len()
    );
    Ok(())
}

/// Everything in `docs/performance.md` from this line on is kept by `bench-report`.
const KEPT_MARKER: &str = "<!-- kept by bench-report: measured by other harnesses -->";

struct Row {
    id: String,
    median_ns: f64,
    lo_ns: f64,
    hi_ns: f64,
}

/// Walks `target/criterion` for `new/benchmark.json` + `new/estimates.json` pairs.
fn collect(dir: &Path) -> Result<Vec<Row>> {
    let mut rows = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        let Ok(entries) = std::fs::read_dir(&d) else {
            continue;
        };
        for entry in entries {
            let path = entry?.path();
            if path.is_dir() {
                if path.file_name().is_some_and(|n| n == "new") {
                    if let Some(row) = read_row(&path)? {
                        rows.push(row);
                    }
                } else if path
                    .file_name()
                    .is_some_and(|n| n != "report" && n != "base")
                {
                    stack.push(path);
                }
            }
        }
    }
    Ok(rows)
}

fn read_row(new_dir: &Path) -> Result<Option<Row>> {
    let bench = new_dir.join("benchmark.json");
    let est = new_dir.join("estimates.json");
    if !bench.exists() || !est.exists() {
        return Ok(None);
    }
    let bench: Value = serde_json::from_str(&std::fs::read_to_string(&bench)?)?;
    let est: Value = serde_json::from_str(&std::fs::read_to_string(&est)?)?;
    let id = bench["full_id"]
        .as_str()
        .ok_or("benchmark.json without full_id")?
        .to_string();
    let median = &est["median"];
    let get = |v: &Value| v.as_f64().ok_or("estimates.json without a median");
    Ok(Some(Row {
        id,
        median_ns: get(&median["point_estimate"])?,
        lo_ns: get(&median["confidence_interval"]["lower_bound"])?,
        hi_ns: get(&median["confidence_interval"]["upper_bound"])?,
    }))
}

fn human(ns: f64) -> String {
    if ns < 1_000.0 {
        format!("{ns:.0} ns")
    } else if ns < 1_000_000.0 {
        format!("{:.2} us", ns / 1_000.0)
    } else if ns < 1_000_000_000.0 {
        format!("{:.2} ms", ns / 1_000_000.0)
    } else {
        format!("{:.2} s", ns / 1_000_000_000.0)
    }
}

fn machine() -> String {
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|m| m.trim().to_string())
        })
        .unwrap_or_else(|| "unknown CPU".to_string());
    let cores = std::thread::available_parallelism().map_or(0, usize::from);
    let rustc = Command::new("rustc")
        .arg("--version")
        .output()
        .ok()
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
        .unwrap_or_default();
    let date = Command::new("date")
        .args(["-u", "+%Y-%m-%d"])
        .output()
        .ok()
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
        .unwrap_or_default();
    format!("{cpu}, {cores} cores available, {rustc}, measured {date} (UTC)")
}

fn render(rows: &[Row], machine: &str) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# Performance\n");
    let _ = writeln!(
        s,
        "Generated by `cargo xtask bench-report` from criterion's estimates \
         (`target/criterion/*/new/estimates.json`); do not edit by hand.\n"
    );
    let _ = writeln!(s, "Machine: {machine}.\n");
    let _ = writeln!(
        s,
        "The machines are shared and noisy: read medians, and compare ratios measured in the \
         same run rather than absolute times across runs.\n"
    );
    let _ = writeln!(
        s,
        "| benchmark | median | 95 % CI of the median | target | within target | note |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|");
    for r in rows {
        let t = TARGETS.iter().find(|t| t.id == r.id);
        let (target, ok) = match t.and_then(|t| t.target_ns) {
            Some(ns) => (human(ns), if r.median_ns <= ns { "yes" } else { "**no**" }),
            None => ("-".to_string(), "-"),
        };
        let note = t.map_or("", |t| t.note);
        let _ = writeln!(
            s,
            "| `{}` | {} | {} - {} | {} | {} | {} |",
            r.id,
            human(r.median_ns),
            human(r.lo_ns),
            human(r.hi_ns),
            target,
            ok,
            note
        );
    }
    let median = |id: &str| rows.iter().find(|r| r.id == id).map(|r| r.median_ns);
    let mut ratio_lines = String::new();
    for (num, den, limit, note) in RATIOS {
        if let (Some(a), Some(b)) = (median(num), median(den)) {
            let ratio = a / b;
            let ok = if ratio <= *limit { "yes" } else { "**no**" };
            let _ = writeln!(
                ratio_lines,
                "| `{num}` / `{den}` | {ratio:.2} | <= {limit} | {ok} | {note} |"
            );
        }
    }
    if !ratio_lines.is_empty() {
        let _ = writeln!(s, "\nRatios within this run:\n");
        let _ = writeln!(s, "| ratio | value | bound | within bound | note |");
        let _ = writeln!(s, "|---|---|---|---|---|");
        s.push_str(&ratio_lines);
    }
    s
}
