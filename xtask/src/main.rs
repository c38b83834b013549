//! Project chores, run as `cargo xtask <command>`.
//!
//! Each command lives in its own module; `main` only dispatches. Commands that write data
//! (golden files, tables in `docs/`) are the only way those files are produced, so anyone can
//! regenerate them.

use std::process::ExitCode;

mod bags;
mod bench_report;
mod compare;
mod detector_accuracy;
mod dictionaries;
mod dictionary;
mod dukf_table;
mod figures;
mod fingerprint;
mod grazing;
mod motion_sets;
mod photos;
mod pyenv;
mod random_scenes;
mod release;
mod ros2_interop;
mod solvepnp;
mod unused_deps;

/// `shared/realdata/<sub>` beside the repository (`../shared`), or beside one of its
/// ancestors (a git worktree lives deeper), or `$FORMATION_REALDATA/<sub>`.
fn realdata(root: &std::path::Path, sub: &str) -> Result<std::path::PathBuf> {
    if let Some(dir) = std::env::var_os("FORMATION_REALDATA") {
        return Ok(std::path::PathBuf::from(dir).join(sub));
    }
    root.ancestors()
        .map(|a| a.join("shared/realdata").join(sub))
        .find(|d| d.is_dir())
        .ok_or_else(|| {
            format!(
                "cannot find shared/realdata/{sub} beside the repository (set FORMATION_REALDATA)"
            )
            .into()
        })
}

type Result<T = ()> = std::result::Result<T, Box<dyn std::error::Error>>;

/// The repository's root folder (the parent of `xtask/`).
fn workspace_root() -> Result<std::path::PathBuf> {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map(std::path::Path::to_path_buf)
        .ok_or_else(|| "xtask has no parent directory".into())
}

/// Writes `text` to a temporary file beside `path` (its name and `.tmp`), then renames it
/// over `path`, so that an interrupted run leaves the old file whole.
fn write_atomically(path: &std::path::Path, text: &str) -> Result {
    let mut name = path.file_name().ok_or("no file name")?.to_os_string();
    name.push(".tmp");
    let tmp = path.with_file_name(name);
    std::fs::write(&tmp, text)?;
    std::fs::rename(&tmp, path)?;
    Ok(())
}

const USAGE: &str = "usage: cargo xtask <command>

commands:
  no-c             fail if any crate in the dependency tree builds C code
  bench-report     run all criterion benchmarks and write docs/performance.md
                   (--quick: short measurements; --no-run: only rebuild the table)
  detector-accuracy  measure the marker detector on synthetic scenes and write
                   docs/detector-accuracy.md (--quick: fewer scenes; --motion-blur,
                   --sizes: print only those tables)
  dictionary       regenerate crates/fiducial/data/dict-4x5-d6.txt (--check: only compare)
  fingerprint      regenerate fixtures/fingerprints/fiducial.txt, the detector's output on
                   fixed frames through every entry point (--check: only compare)
  dictionaries     regenerate the standard families' tables (crates/fiducial/data/families/)
                   and fixtures/markers/ from OpenCV in target/py-venv (--check: only compare)
  random-scenes    score 100 seeded random scenes, write docs/random-scenes.md
                   (--count N, --seed S; --check: only compare)
  dukf-table       run the dual-UKF reproduction over seeds 1..20 (with and without
                   the paper's bias) and write docs/dukf-reproduction.md
                   (--scenario FILE: that scenario file against the baselines, printed;
                   --held-out: the follower on its estimate against baselines tuned on
                   seeds 1..20, held-out seeds 101..120, docs/dukf-held-out.md; runs a
                   filterpy UKF in target/py-venv)
  compare          ours side by side with OpenCV ArUco, AprilTag 3 (pupil-apriltags), OpenCV
                   solvePnP and a filterpy UKF on identical inputs, in a Python venv under
                   target/py-venv; writes docs/comparison.md and docs/img/comparison-*.svg
                   (--quick: few scenes; --scenes N: scenes per condition at 640x480)
  motion-sets      issue #31's motion-blur item: ours against OpenCV ArUco and AprilTag 3
                   (compare's renderer, peers and scoring) on nine held-out 640x480 scene
                   sets varying marker size, blur length and direction; writes
                   docs/motion-blur-sets.md (--scenes N per set, default 40; --quick: 5)
  photos           time our detector on the real photographs of shared/realdata (no markers,
                   the NASA robots, OpenCV's ArUco photo, Duckietown) and print, per photo,
                   the median time, the reads and where the work went (--reps N, default 20;
                   --dictionary NAME, default tag36h11; --clutter: the clutter bench's
                   frame too; --list: every marker read; or name photos/folders to time)
  grazing          markers seen at a grazing angle (the NASA photo's tag 8, drawn with an exact
                   truth): ours against AprilTag 3 (pupil-apriltags in target/py-venv); writes
                   docs/grazing-angles.md (--markers N per row, default 20)
  unused-deps      fail if a workspace crate declares a dependency its code never names
  figures          run the demo and copy its figures into docs/img/ (the README's)
  solvepnp         OpenCV's single-marker poses (solvePnP IPPE_SQUARE) and lens projections
                   for pose's tests, in a Python venv under target/py-venv; writes
                   fixtures/opencv/ (--cases FILE: corner sets to use, --out FILE)
  bags             write the fixture ROS 2 bags in fixtures/bags/ with the Python rosbags and
                   mcap-ros2-support packages (venv in target/py-venv), the folder path's
                   estimates on the same frames, and check our --mcap output with the
                   Python mcap reader (--frames N: demo frames in demo_zstd.mcap, default 16)
  ros2-interop     formation-tracker ros2 against CycloneDDS (pip cyclonedds, venv in
                   target/py-venv) in a private network namespace: it publishes Image,
                   CameraInfo and Odometry, decodes every message the node publishes and
                   checks them against the node's JSON (--frames N: frames tracked, default
                   150; --lenient: tolerate a leader's first and the last frame's messages lost)
";

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let result = match args.first().map(String::as_str) {
        Some("no-c") => no_c(),
        Some("bench-report") => bench_report::run(&args[1..]),
        Some("dictionary") => dictionary::run(&args[1..]),
        Some("fingerprint") => fingerprint::run(&args[1..]),
        Some("dictionaries") => dictionaries::run(&args[1..]),
        Some("random-scenes") => random_scenes::run(&args[1..]),
        Some("detector-accuracy") => detector_accuracy::run(&args[1..]),
        Some("dukf-table") => dukf_table::run(&args[1..]),
        Some("unused-deps") => unused_deps::run(&args[1..]),
        Some("figures") => figures::run(&args[1..]),
        Some("solvepnp") => solvepnp::run(&args[1..]),
        Some("bags") => bags::run(&args[1..]),
        Some("photos") => photos::run(&args[1..]),
        Some("grazing") => grazing::run(&args[1..]),
        Some("compare") => compare::run(&args[1..]),
        Some("motion-sets") => motion_sets::run(&args[1..]),
        Some("ros2-interop") => ros2_interop::run(&args[1..]),
        _ => {
            eprint!("{USAGE}");
            return ExitCode::from(2);
        }
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("xtask: error: {err}");
            ExitCode::FAILURE
        }
    }
}

/// `cargo metadata --format-version 1` with `extra` arguments, parsed.
pub fn cargo_metadata(
    extra: &[&str],
) -> std::result::Result<serde_json::Value, Box<dyn std::error::Error>> {
    let out = std::process::Command::new(env!("CARGO"))
        .args(["metadata", "--format-version", "1"])
        .args(extra)
        .output()?;
    if !out.status.success() {
        return Err(format!(
            "cargo metadata failed: {}",
            String::from_utf8_lossy(&out.stderr)
        )
        .into());
    }
    Ok(serde_json::from_slice(&out.stdout)?)
}

/// Crates whose presence means C is compiled or a system library is linked.
const C_BUILDERS: &[&str] = &["cc", "cmake", "pkg-config", "bindgen", "alloca"];

/// Fails if a crate in the tree compiles C or links a native library: one of
/// [`C_BUILDERS`], or a `-sys` crate with a build script or a `links` key (how a binding
/// finds and links its library: `openssl-sys`, `zstd-sys`, ...). A `-sys` name alone is not
/// the test: `netlink-sys` (RustDDS's interface listing) is Rust declarations of kernel
/// socket constants, with no build script and nothing linked; and `links` alone is not
/// either: `rayon-core` sets it only to forbid two copies of itself.
fn no_c() -> Result {
    let out = std::process::Command::new(env!("CARGO"))
        .args([
            "tree",
            "--workspace",
            "-e",
            "normal,build,dev",
            "--prefix",
            "none",
        ])
        .output()?;
    if !out.status.success() {
        return Err(format!(
            "cargo tree failed: {}",
            String::from_utf8_lossy(&out.stderr)
        )
        .into());
    }
    let tree = String::from_utf8(out.stdout)?;
    let in_tree: std::collections::BTreeSet<(String, String)> = tree
        .lines()
        .filter_map(|line| {
            let mut words = line.split_whitespace();
            let name = words.next()?;
            let version = words.next()?.trim_start_matches('v');
            Some((name.to_owned(), version.to_owned()))
        })
        .collect();
    let meta = cargo_metadata(&["--locked"])?;
    let packages = meta["packages"]
        .as_array()
        .ok_or("cargo metadata: no packages")?;
    let mut offenders = Vec::new();
    for p in packages {
        let (Some(name), Some(version)) = (p["name"].as_str(), p["version"].as_str()) else {
            continue;
        };
        if !in_tree.contains(&(name.to_owned(), version.to_owned())) {
            continue;
        }
        let build_script = p["targets"].as_array().is_some_and(|targets| {
            targets.iter().any(|t| {
                t["kind"]
                    .as_array()
                    .is_some_and(|k| k.iter().any(|k| k == "custom-build"))
            })
        });
        let binding = name.ends_with("-sys") && (build_script || !p["links"].is_null());
        if C_BUILDERS.contains(&name) || binding {
            offenders.push(format!("{name} v{version}"));
        }
    }
    if offenders.is_empty() {
        println!(
            "no-c: none of the {} crates in the tree builds C or links a native library",
            in_tree.len()
        );
        Ok(())
    } else {
        Err(format!("crates that build C: {}", offenders.join(", ")).into())
    }
}
