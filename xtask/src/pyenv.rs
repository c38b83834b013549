//! The one Python virtual environment of the xtask commands that run the peers (OpenCV for
//! `dictionaries`, `solvepnp` and `compare`, the ROS 2 bag packages for `bags`, pupil-apriltags
//! and filterpy for `compare`): `target/py-venv`, made
//! on first use, each command's pinned packages pip-installed when its import probe fails.
//! One place for the pins, so that the commands sharing the venv never ask pip for two
//! versions of one package.

use std::path::{Path, PathBuf};
use std::process::Command;

use crate::Result;

/// OpenCV with the aruco module, pinned (the dictionaries' tables and the solvePnP
/// references are generated with it; pinned so that `dictionaries --check` is
/// reproducible).
pub const OPENCV: &str = "opencv-contrib-python-headless==5.0.0.93";

/// AprilTag 3's Python bindings, pinned (the AprilTag peer of `compare`).
pub const APRILTAGS: &str = "pupil-apriltags==1.0.4.post11";

/// filterpy, pinned (the UKF peer of `compare`).
pub const FILTERPY: &str = "filterpy==2.0.0";

/// NumPy, pinned (OpenCV's and the bag writers' arrays).
pub const NUMPY: &str = "numpy==2.4.6";

/// The venv's python under `root/target/py-venv`, with `packages` installed when the Python
/// line `probe` (imports) fails there. `who` names the command in the progress line.
///
/// # Errors
/// `python3 -m venv` or `pip install` failed (the message says which).
pub fn python(root: &Path, who: &str, packages: &[&str], probe: &str) -> Result<PathBuf> {
    let dir = root.join("target").join("py-venv");
    let python = dir.join("bin").join("python");
    if !python.exists() {
        eprintln!("{who}: making {}", dir.display());
        let status = Command::new("python3")
            .args(["-m", "venv"])
            .arg(&dir)
            .status()?;
        if !status.success() {
            return Err(format!(
                "python3 -m venv {} failed ({status}; is python3 with venv installed?)",
                dir.display()
            )
            .into());
        }
    }
    let have = Command::new(&python)
        .args(["-c", probe])
        .status()
        .is_ok_and(|s| s.success());
    if !have {
        eprintln!("{who}: pip install {}", packages.join(" "));
        let status = Command::new(&python)
            .args(["-m", "pip", "install", "-q"])
            .args(packages)
            .status()?;
        if !status.success() {
            return Err(format!("pip install {} failed ({status})", packages.join(" ")).into());
        }
    }
    Ok(python)
}

/// Runs `python script args...` (inheriting stdout and stderr, so the script's own messages
/// reach the terminal) and waits for it.
///
/// # Errors
/// The script could not be started, or it exited unsuccessfully (the message names the
/// interpreter, the script and the exit status).
pub fn run_script<A: AsRef<std::ffi::OsStr>>(python: &Path, script: &Path, args: &[A]) -> Result {
    let status = Command::new(python).arg(script).args(args).status()?;
    if status.success() {
        Ok(())
    } else {
        Err(format!(
            "{} {} failed ({status})",
            python.display(),
            script.display()
        )
        .into())
    }
}
