//! The `formation-tracker` command-line tool.
//!
//! Each subcommand lives in its own module under `cmd/`; this file only parses arguments,
//! dispatches, and reports an error as one clear line on stderr with a non-zero exit code.

#![deny(clippy::print_stderr)] // stderr goes through cmd::progress::errln! (a closed stderr must not panic)

use std::process::ExitCode;

use clap::{Parser, Subcommand};

mod cmd;

/// Vision-based tracking of mobile robots in formation.
///
/// A follower robot's camera finds the leader robots' marker rigs, measures their pose and
/// estimates the formation variables (l12, alpha12, beta12) and the leaders' velocities with
/// a dual unscented Kalman filter.
#[derive(Debug, Parser)]
#[command(
    name = "formation-tracker",
    version,
    about,
    long_about = None,
    after_help = "Exit codes: 0 everything asked for was done; 1 error, nothing usable (one line on \
                  stderr); 2 bad usage (an unknown option, a value out of range); 3 partial, some \
                  images or frames could not be used (the others were reported). A reader that \
                  closes the pipe (`| head`) ends a command quietly with 0. `track` and `demo` stopped by \
                  SIGINT (Ctrl-C) or SIGTERM finish the frame in hand, close their outputs \
                  and exit with 130 or 143. Outputs are written under temporary names and \
                  renamed into place only when complete. See docs/reliability.md."
)]
struct Cli {
    /// No progress on stderr (bar or periodic status lines); results and errors still print.
    #[arg(long, short, global = true)]
    quiet: bool,
    /// The memory the run may use for its inputs: images, y4m frames and bag chunks larger
    /// than a quarter of it are refused from their headers (1GiB, 512MiB, 64M or bytes; at
    /// least 16MiB; docs/reliability.md).
    #[arg(long, global = true, value_name = "SIZE", default_value = "1GiB",
          value_parser = formation_io::limits::parse_bytes)]
    max_memory: u64,
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Print the name and version of every package this binary was built from, one per line.
    Info,
    /// Find and read the markers in images (PNG/JPEG); --json for one JSON line per image.
    Detect(cmd::detect::Args),
    /// Track leader robots through camera frames (a folder of images, a y4m file or stdin).
    Track(cmd::track::Args),
    /// Write print-ready marker images for every robot's rig (PNGs that carry their print
    /// resolution, and SVGs in millimetres) and markers.json.
    Markers(cmd::markers::Args),
    /// Render a synthetic frame of a paper scene (Figs. 7-11) or a scene file, with its truth.
    Render(cmd::render::Args),
    /// Regenerate one of the paper's results (e.g. `reproduce dukf`, Figs. 12-13).
    Reproduce(cmd::reproduce::Args),
    /// Run the tracker as a ROS 2 node: live camera frames and odometry in, leaders' poses,
    /// velocities and formation variables out; with --control it drives the follower
    /// (docs/ros2.md).
    Ros2(Box<cmd::ros2::node::Args>),
    /// Publish a recording (demo --save-frames) on ROS 2 as a camera and odometry would.
    #[command(name = "ros2-sim")]
    Ros2Sim(cmd::ros2::sim::Args),
    /// Run the end-to-end demo: the reference scenario rendered on the follower's camera,
    /// detected, posed and tracked, with an occlusion (out/demo).
    Demo(cmd::demo::Args),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    cmd::progress::set_quiet(cli.quiet);
    formation_io::limits::set_max_memory(cli.max_memory);
    let result: Result<(), cmd::CliError> = match cli.command {
        Command::Info => cmd::info::run(),
        Command::Markers(args) => cmd::markers::run(&args),
        Command::Detect(args) => cmd::detect::run(&args),
        Command::Track(args) => cmd::track::run(&args),
        Command::Render(args) => cmd::render::run(&args),
        Command::Reproduce(args) => cmd::reproduce::run(args),
        Command::Demo(args) => cmd::demo::run(args),
        Command::Ros2(args) => cmd::ros2::node::run(*args),
        Command::Ros2Sim(args) => cmd::ros2::sim::run(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        // The reader closed the pipe: nothing more is wanted, which is not a failure.
        Err(err)
            if err
                .downcast_ref::<cmd::StdoutError>()
                .is_some_and(cmd::StdoutError::is_closed_pipe) =>
        {
            ExitCode::SUCCESS
        }
        Err(err) if err.downcast_ref::<cmd::Partial>().is_some() => {
            cmd::progress::errln!("formation-tracker: warning: {}", one_line(&err.to_string()));
            ExitCode::from(cmd::EXIT_PARTIAL)
        }
        Err(err) => {
            cmd::remove_created_dirs();
            let (code, kind) = if let Some(i) = err.downcast_ref::<cmd::interrupt::Interrupted>() {
                (i.exit_code(), "stopped")
            } else if err.downcast_ref::<cmd::Usage>().is_some() {
                (cmd::EXIT_USAGE, "error")
            } else {
                (1, "error")
            };
            cmd::progress::errln!("formation-tracker: {kind}: {}", one_line(&err.to_string()));
            ExitCode::from(code)
        }
    }
}

/// An error message on one line: a library message that spans several lines (a parser's
/// drawing of the offending line) keeps its first non-empty line.
fn one_line(message: &str) -> &str {
    message
        .lines()
        .map(str::trim)
        .find(|l| !l.is_empty())
        .unwrap_or("unknown error")
}
