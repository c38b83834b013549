//! One module per subcommand. Each exposes an `Args` struct (clap) and a `run` function.

/// Any error a subcommand reports; printed as one line by `main`.
pub type CliError = Box<dyn std::error::Error + Send + Sync + 'static>;

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
        Some(path) => formation_tracker::rig::RigModel::load(path, dictionary)?,
        None => formation_tracker::rig::RigModel::reference(),
    })
}

pub mod demo;
pub mod detect;
pub mod detect_robots;
pub mod info;
pub mod markers;
pub mod render;
pub mod reproduce;
pub mod reproduce_scenes;
pub mod track;
