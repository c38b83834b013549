//! `formation-tracker track`: camera frames in, formation variables and leader velocities
//! out, one line per frame.

use std::io::Write;
use std::path::PathBuf;

use clap::Args as ClapArgs;
use fiducial::{Detector, DetectorConfig, Dictionary};
use formation_tracker::mount::CameraMount;
use formation_tracker::pipeline::{Pipeline, PipelineError, PipelineFrame};
use formation_tracker::rig::RigModel;
use formation_tracker::robots::RobotConfig;
use formation_tracker::tracker::{LeaderReport, Tracker, TrackerConfig};
use formation_tracker_cli::frames::FrameSource;
use formation_tracker_cli::inputs::FollowerInputs;
use pose::PoseSolver;
use pose::calib::Calibration;
use serde::Serialize;
use unicycle::Inputs;

use super::CliError;

/// Track leader robots through a stream of camera frames.
///
/// INPUT is a folder of PNG/JPEG images (sorted by name), a y4m file, or `-` for a y4m stream
/// on stdin, e.g. `ffmpeg -i video.mp4 -f yuv4mpegpipe -pix_fmt yuv420p - | formation-tracker
/// track - --camera cam.yaml`. Prints one line per frame on stdout (JSON with --json).
#[derive(Debug, ClapArgs)]
pub struct Args {
    /// A folder of images, a y4m file, or `-` for y4m on stdin.
    #[arg(value_name = "INPUT")]
    input: PathBuf,
    /// Camera calibration (OpenCV YAML or ROS camera_info).
    #[arg(long, value_name = "FILE")]
    camera: PathBuf,
    /// Rig file (YAML/JSON); default: the reference rig.
    #[arg(long, value_name = "FILE")]
    rig: Option<PathBuf>,
    /// Follower inputs per frame: CSV with `frame` or `t`, `v2`, `w2`, optional `pan`.
    #[arg(long, value_name = "CSV")]
    inputs: Option<PathBuf>,
    /// Frame rate, 0.001 to 10000 frames/s; default: the y4m header's, else 30.
    #[arg(long, value_name = "F", value_parser = super::numbers::fps)]
    fps: Option<f64>,
    /// One JSON object per frame instead of a text line.
    #[arg(long)]
    json: bool,
    /// Camera offset ahead of the follower's axle, metres (the paper's d).
    #[arg(long, value_name = "M", default_value_t = CameraMount::default().offset,
          value_parser = super::numbers::non_negative, allow_hyphen_values = true)]
    mount_offset: f64,
    /// Camera height above the ground, metres.
    #[arg(long, value_name = "M", default_value_t = CameraMount::default().height,
          value_parser = super::numbers::finite, allow_hyphen_values = true)]
    mount_height: f64,
    /// Camera tilt below the horizontal, radians.
    #[arg(long, value_name = "RAD", default_value_t = 0.0,
          value_parser = super::numbers::finite, allow_hyphen_values = true)]
    mount_tilt: f64,
    /// Camera pan (left positive), radians, when the inputs CSV has no `pan` column.
    #[arg(long, value_name = "RAD", default_value_t = 0.0,
          value_parser = super::numbers::finite, allow_hyphen_values = true)]
    pan: f64,
    /// Accept frames whose size differs from the calibration's by scaling the intrinsics
    /// (frames resized from the calibrated camera's, same aspect ratio). Without it such
    /// frames are errors: their poses would be wrong by the scale.
    #[arg(long = "scale-calibration")]
    scale_calibration: bool,
    /// Largest image side accepted, pixels; larger frames are refused from their header,
    /// before they are decoded.
    #[arg(long, value_name = "PX", default_value_t = formation_tracker_cli::frames::MAX_SIDE,
          value_parser = super::numbers::max_side)]
    max_side: usize,
    /// Seconds without a measurement before a track is dropped.
    #[arg(long, value_name = "S", default_value_t = 2.0, value_parser = super::numbers::positive)]
    lost_after: f64,
}

#[derive(Serialize)]
struct Line<'a> {
    frame: u64,
    /// Where the frame came from: the image file, or `INPUT#N` for frame N of a y4m stream.
    source: &'a str,
    t: f64,
    leaders: &'a [LeaderReport],
    markers: usize,
    failures: &'a [String],
    timing: TimingOut,
}

#[derive(Serialize)]
struct TimingOut {
    detect_ms: f64,
    pose_ms: f64,
    track_ms: f64,
    total_ms: f64,
}

/// Runs `track`.
pub fn run(args: &Args) -> Result<(), CliError> {
    let calibration = Calibration::from_file(&args.camera)?;
    let dict = Dictionary::paper();
    let rig = super::load_rig(args.rig.as_deref(), dict)?;
    let mut frames = FrameSource::open_with_max_side(&args.input, args.max_side)?;
    let fps = frame_rate(args, &frames)?;
    let inputs = match &args.inputs {
        Some(path) => Some(FollowerInputs::from_path(path)?),
        None => {
            eprintln!(
                "track: no --inputs: assuming the follower stands still (v2 = w2 = 0, pan {})",
                args.pan
            );
            None
        }
    };
    let mount = CameraMount {
        offset: args.mount_offset,
        height: args.mount_height,
        pan: args.pan,
        tilt: args.mount_tilt,
    };
    // Built at the first frame, whose size the calibration is scaled to with
    // --scale-calibration.
    let mut pipeline: Option<Pipeline> = None;
    let mut progress = super::progress::Progress::new("track", "frames", frames.len_hint());
    let stdout = std::io::stdout();
    let mut out = std::io::BufWriter::new(stdout.lock());
    let (mut broken, mut processed) = (0u64, 0u64);
    loop {
        let frame = match frames.next_frame() {
            Ok(Some(frame)) => frame,
            Ok(None) => break,
            Err(e) => {
                broken += 1;
                progress.println(&format!("track: {e}"));
                continue;
            }
        };
        progress.inc();
        let index = frame.index;
        let source = frame.file.map_or_else(
            || format!("{}#{index}", args.input.display()),
            |file| file.display().to_string(),
        );
        let t = index as f64 / fps;
        let (follower, pan) = match inputs.as_ref().and_then(|i| i.at(index, t)) {
            Some(s) => (s.inputs, s.pan.unwrap_or(args.pan)),
            None => (Inputs::new(0.0, 0.0), args.pan),
        };
        let image = frame.image;
        let pipeline = match &mut pipeline {
            Some(pipeline) => pipeline,
            None => {
                let calibration = if args.scale_calibration {
                    calibration.scaled_to(image.width as u32, image.height as u32)?
                } else {
                    calibration
                };
                pipeline.insert(build_pipeline(args, calibration, rig.clone(), mount, fps)?)
            }
        };
        let result = pipeline.process(
            &image.data,
            image.width,
            image.height,
            t,
            follower,
            CameraMount { pan, ..mount },
        );
        match result {
            Ok(done) => {
                processed += 1;
                write_frame(&mut out, args.json, index, &source, t, &done)?;
            }
            Err(e) => {
                broken += 1;
                let hint = if matches!(e, PipelineError::SizeMismatch { .. }) {
                    " (pass --scale-calibration if the frames were resized from the calibrated camera's)"
                } else {
                    ""
                };
                progress.println(&format!("track: frame {index}: {e}{hint}"));
            }
        }
    }
    out.flush().map_err(super::StdoutError)?;
    progress.finish();
    let truncated = if frames.truncated() {
        "; the stream ended inside a frame (truncated), which was dropped"
    } else {
        ""
    };
    let summary = format!("{processed} frames tracked, {broken} broken{truncated}");
    if processed == 0 {
        return Err(format!("nothing tracked: {summary}").into());
    }
    if broken > 0 || frames.truncated() {
        return Err(super::Partial(summary).into());
    }
    eprintln!("track: {summary}");
    Ok(())
}

/// `--fps`, else the stream's own rate, else 30 (said on stderr).
fn frame_rate(args: &Args, frames: &FrameSource) -> Result<f64, CliError> {
    let fps = match (args.fps, frames.frame_rate()) {
        (Some(f), _) => f,
        (None, Some(f)) => f,
        (None, None) => {
            eprintln!("track: no --fps and no frame rate in the input: assuming 30 frames/s");
            30.0
        }
    };
    Ok(super::numbers::check_fps(fps).map_err(|e| format!("the input's frame rate: {e}"))?)
}

/// The detector, the calibrated solver, the rig and the tracker, in one pipeline.
fn build_pipeline(
    args: &Args,
    calibration: Calibration,
    rig: RigModel,
    mount: CameraMount,
    fps: f64,
) -> Result<Pipeline, CliError> {
    let mut config = TrackerConfig::reference(mount.offset, 1.0 / fps);
    config.lost_after = args.lost_after;
    let tracker = Tracker::new(config)?;
    let solver = PoseSolver::new(calibration.intrinsics).with_distortion(calibration.distortion);
    // The rig's dictionary: our own unless the rig file names another (e.g. tag36h11).
    let dictionary = rig.marker_dictionary()?.clone();
    Ok(Pipeline::new(
        Detector::with_dictionary(DetectorConfig::default(), dictionary),
        solver,
        (calibration.width, calibration.height),
        rig,
        RobotConfig::default(),
        tracker,
    ))
}

/// One frame's line: JSON with `--json`, else text.
fn write_frame(
    out: &mut impl Write,
    json: bool,
    index: u64,
    source: &str,
    t: f64,
    done: &PipelineFrame,
) -> Result<(), CliError> {
    use std::fmt::Write as _;
    let mut text = String::new();
    let timing = TimingOut {
        detect_ms: done.timing.detect_ms,
        pose_ms: done.timing.pose_ms,
        track_ms: done.timing.track_ms,
        total_ms: done.timing.total_ms(),
    };
    if json {
        let line = Line {
            frame: index,
            source,
            t,
            leaders: &done.report.leaders,
            markers: done.markers,
            failures: &done.failures,
            timing,
        };
        out.write_all(format!("{}\n", serde_json::to_string(&line)?).as_bytes())
            .map_err(super::StdoutError)?;
        return Ok(());
    }
    write!(text, "frame {index} t {t:.3}:")?;
    if done.report.leaders.is_empty() {
        write!(text, " no leader")?;
    }
    for l in &done.report.leaders {
        write!(
            text,
            " robot {} {:?} l12 {:.3} alpha12 {:.3} beta12 {:.3} v1 {:.2} w1 {:.2};",
            l.robot, l.status, l.l12, l.alpha12, l.beta12, l.v1, l.w1
        )?;
    }
    writeln!(text, " ({:.1} ms)", timing.total_ms)?;
    out.write_all(text.as_bytes()).map_err(super::StdoutError)?;
    Ok(())
}
