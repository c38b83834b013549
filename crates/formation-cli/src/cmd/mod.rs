//! One module per subcommand. Each exposes an `Args` struct (clap) and a `run` function.

/// Any error a subcommand reports; printed as one line by `main`.
pub type CliError = Box<dyn std::error::Error + Send + Sync + 'static>;

/// Exit code of a command that used some of its inputs and not others (`docs/reliability.md`).
pub const EXIT_PARTIAL: u8 = 3;

/// Some inputs (images, frames) could not be used while others were: what was printed is
/// valid but incomplete. `main` prints the message as one warning line and exits with
/// [`EXIT_PARTIAL`]; when *no* input was usable a command returns an ordinary error (exit 1).
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct Partial(pub String);

/// A usage error found after parsing (an output that is one of the inputs, options that
/// cannot go together): `main` prints it as one error line and exits with
/// [`EXIT_USAGE`], as clap does for the errors it finds itself (`docs/reliability.md`).
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct Usage(pub String);

/// Exit code of a usage error (`docs/reliability.md`).
pub const EXIT_USAGE: u8 = 2;

/// Writing to standard output failed. `main` ends quietly with exit code 0 when the reader
/// closed the pipe (`formation-tracker detect *.png | head -n 1`), as command-line tools do,
/// and reports anything else (a full disk, `> /dev/full`) as one error line with exit code 1.
#[derive(Debug, thiserror::Error)]
#[error("cannot write to standard output: {0}")]
pub struct StdoutError(#[from] pub std::io::Error);

impl StdoutError {
    /// Whether the reader went away (a closed pipe), which is not a failure.
    pub fn is_closed_pipe(&self) -> bool {
        self.0.kind() == std::io::ErrorKind::BrokenPipe
    }
}

/// Writes `text` to standard output and flushes it, so that a failed write is seen here
/// and not as a panic inside `println!`. Every command's stdout goes through this (or, for
/// streams, through a writer whose errors become [`StdoutError`]).
pub fn write_stdout(text: std::fmt::Arguments<'_>) -> Result<(), StdoutError> {
    use std::io::Write as _;
    let mut out = std::io::stdout().lock();
    out.write_fmt(text)?;
    out.flush()?;
    Ok(())
}

/// `println!` for commands: the line goes through [`write_stdout`], and a failed write is an
/// error the caller returns with `?`.
macro_rules! outln {
    ($($arg:tt)*) => {
        $crate::cmd::write_stdout(format_args!("{}\n", format_args!($($arg)*)))
    };
}
pub(crate) use outln;

/// The rig of `--rig FILE`, or the reference rig of spec 3.3 without one: every command that
/// takes `--rig` reads it here, so they all agree.
pub fn load_rig(
    path: Option<&std::path::Path>,
    dictionary: &fiducial::Dictionary,
) -> Result<formation_tracker::rig::RigModel, CliError> {
    Ok(match path {
        Some(path) => formation_io::rigfile::load(path, dictionary)?,
        None => formation_tracker::rig::RigModel::reference(),
    })
}

/// The calibration file `path` (`--camera`), every error naming the file.
pub fn load_calibration(path: &std::path::Path) -> Result<pose::Camera, CliError> {
    use pose::Camera;
    use pose::calib::CalibrationError;
    Camera::from_file(path).map_err(|e| match e {
        // Already names the file.
        CalibrationError::Io { .. } => e.into(),
        e => format!("{}: {e}", path.display()).into(),
    })
}

/// Creates the output directory `dir` if needed and checks that a file can be written into
/// it, before any long work starts (a demo that renders for 11 s and then cannot write
/// is a wasted run).
pub fn prepare_out_dir(dir: &std::path::Path) -> Result<(), CliError> {
    let fail =
        |e: std::io::Error| format!("cannot write to output directory {}: {e}", dir.display());
    // The folders this creates, outermost first, so that a failed run can take them back.
    let mut missing: Vec<std::path::PathBuf> = dir
        .ancestors()
        .take_while(|d| !d.as_os_str().is_empty() && !d.exists())
        .map(std::path::Path::to_path_buf)
        .collect();
    missing.reverse();
    std::fs::create_dir_all(dir).map_err(fail)?;
    if let Ok(mut created) = CREATED_DIRS.lock() {
        created.extend(missing);
    }
    let probe = dir.join(format!(".formation-tracker-probe-{}", std::process::id()));
    std::fs::write(&probe, b"").map_err(fail)?;
    std::fs::remove_file(&probe).map_err(fail)?;
    Ok(())
}

/// The output folders [`prepare_out_dir`] created in this run, outermost first.
static CREATED_DIRS: std::sync::Mutex<Vec<std::path::PathBuf>> = std::sync::Mutex::new(Vec::new());

/// Removes the output folders this run created that are still empty (innermost first): a
/// run that fails or is interrupted writes nothing, not even an empty folder. `main` calls it
/// on every error.
pub fn remove_created_dirs() {
    if let Ok(mut created) = CREATED_DIRS.lock() {
        for dir in created.drain(..).rev() {
            // Fails, as wanted, when the folder holds anything.
            let _ = std::fs::remove_dir(dir);
        }
    }
}

/// [`prepare_out_dir`] for the directory an output file goes into.
pub fn prepare_out_file(file: &std::path::Path) -> Result<(), CliError> {
    match file.parent() {
        Some(dir) if !dir.as_os_str().is_empty() => prepare_out_dir(dir),
        _ => prepare_out_dir(std::path::Path::new(".")),
    }
}

/// Value parsers for numeric options, shared by every command so that `nan`, `inf` and
/// out-of-range values are refused before any work starts, with the same message (clap
/// prints it as `invalid value 'nan' for '--pan <RAD>': ...` and exits with code 2).
pub mod numbers {
    /// Frame rates accepted from `--fps` or a y4m header, frames per second: outside this
    /// range time stops (1e300 frames/s) or stretches (one frame per 30 years).
    pub const FPS_RANGE: std::ops::RangeInclusive<f64> = 1e-3..=1e4;

    fn number(s: &str) -> Result<f64, String> {
        s.trim()
            .parse::<f64>()
            .map_err(|_| format!("`{s}` is not a number"))
    }

    /// Any finite number (negative ones included).
    pub fn finite(s: &str) -> Result<f64, String> {
        let x = number(s)?;
        if x.is_finite() {
            Ok(x)
        } else {
            Err("must be a finite number".into())
        }
    }

    /// A finite number above zero.
    pub fn positive(s: &str) -> Result<f64, String> {
        let x = finite(s)?;
        if x > 0.0 {
            Ok(x)
        } else {
            Err("must be above zero".into())
        }
    }

    /// The follower's odometry noise, `V,W`: two finite non-negative standard deviations,
    /// m/s and rad/s (at most 10 m/s and 10 rad/s, beyond any odometry worth the name).
    pub fn odometry_noise(s: &str) -> Result<[f64; 2], String> {
        let parts: Vec<&str> = s.split(',').collect();
        let [v, w] = parts[..] else {
            return Err(format!(
                "`{s}` is not two numbers `V,W` (m/s, rad/s), e.g. 0.01,0.01"
            ));
        };
        let mut out = [0.0; 2];
        for (slot, (part, unit)) in out.iter_mut().zip([(v, "m/s"), (w, "rad/s")]) {
            let x = finite(part)?;
            if !(0.0..=10.0).contains(&x) {
                return Err(format!(
                    "{} {unit} is not an odometry noise (0 up to 10 {unit})",
                    short(x)
                ));
            }
            *slot = x;
        }
        Ok(out)
    }

    /// An angle in radians within `[-pi, pi]`; a value that would be a plausible angle in
    /// degrees says so (`--pan 30` is 30 rad, not 30 degrees).
    pub fn angle(s: &str) -> Result<f64, String> {
        within_pi(s, std::f64::consts::PI, "-pi to pi")
    }

    /// A camera tilt in radians, within `(-pi/2, pi/2)`: a camera on a robot looks forward,
    /// up or down, never behind itself.
    pub fn tilt(s: &str) -> Result<f64, String> {
        let x = within_pi(s, std::f64::consts::FRAC_PI_2, "-pi/2 to pi/2")?;
        if x.abs() >= std::f64::consts::FRAC_PI_2 {
            return Err(format!(
                "{x} rad is not inside -pi/2 to pi/2 (the camera would look straight up or down)"
            ));
        }
        Ok(x)
    }

    fn within_pi(s: &str, bound: f64, range: &str) -> Result<f64, String> {
        let x = finite(s)?;
        if x.abs() <= bound {
            return Ok(x);
        }
        let hint = if x.abs() <= 360.0 {
            format!("; did you mean {x} degrees = {:.4} rad?", x.to_radians())
        } else {
            String::new()
        };
        Err(format!("{} rad is outside {range} rad{hint}", short(x)))
    }

    /// `x` for a message: plain when it reads well, else in exponent form (`1e308`, not
    /// three hundred digits).
    pub fn short(x: f64) -> String {
        if x != 0.0 && !(1e-4..1e6).contains(&x.abs()) {
            format!("{x:e}")
        } else {
            format!("{x}")
        }
    }

    /// Largest height or offset accepted, metres: a robot's camera is not 100 m up.
    pub const MAX_METRES: f64 = 100.0;

    /// A camera height above the ground, metres: above 0 and below [`MAX_METRES`].
    pub fn height(s: &str) -> Result<f64, String> {
        let x = finite(s)?;
        if x > 0.0 && x < MAX_METRES {
            Ok(x)
        } else {
            Err(format!(
                "{x} m is not a camera height (above 0 and below {MAX_METRES} m)"
            ))
        }
    }

    /// A camera offset ahead of the axle, metres: 0 up to [`MAX_METRES`].
    pub fn offset(s: &str) -> Result<f64, String> {
        let x = finite(s)?;
        if (0.0..MAX_METRES).contains(&x) {
            Ok(x)
        } else {
            Err(format!(
                "{x} m is not a camera offset (0 up to {MAX_METRES} m)"
            ))
        }
    }

    /// The number of robots in the demo's chain, 2 to 6.
    pub fn chain_robots(s: &str) -> Result<usize, String> {
        match s.trim().parse::<usize>() {
            Ok(n) if (2..=6).contains(&n) => Ok(n),
            _ => Err(format!("`{s}` is not a number of robots from 2 to 6")),
        }
    }

    /// The largest image side accepted (`--max-side`), 1 to 1048576 pixels.
    pub fn max_side(s: &str) -> Result<usize, String> {
        match s.trim().parse::<usize>() {
            Ok(n) if (1..=1 << 20).contains(&n) => Ok(n),
            _ => Err(format!(
                "`{s}` is not an image side from 1 to 1048576 pixels"
            )),
        }
    }

    /// A frame rate inside [`FPS_RANGE`].
    pub fn fps(s: &str) -> Result<f64, String> {
        let x = number(s)?;
        check_fps(x)
    }

    /// `fps` if it lies inside [`FPS_RANGE`], else the message naming the range.
    pub fn check_fps(fps: f64) -> Result<f64, String> {
        if FPS_RANGE.contains(&fps) {
            Ok(fps)
        } else {
            Err(format!(
                "{fps} frames/s is outside the valid range {} to {} frames/s",
                FPS_RANGE.start(),
                FPS_RANGE.end()
            ))
        }
    }
}

pub mod demo;
pub mod detect;
pub mod detect_robots;
pub mod info;
pub mod interrupt;
pub mod marker_pose;
pub mod markers;
pub mod output;
pub mod progress;
pub mod render;
pub mod reproduce;
pub mod reproduce_scenes;
pub mod ros2;
pub mod track;
