//! `formation-tracker track`: camera frames in, formation variables and leader velocities
//! out, one line per frame.

use std::io::Write;
use std::path::PathBuf;

use clap::Args as ClapArgs;
use fiducial::{Detector, DetectorConfig, Dictionary};
use formation_io::frames::FrameSource;
use formation_io::inputs::FollowerInputs;
use formation_tracker::guided::GuidedConfig;
use formation_tracker::mount::CameraMount;
use formation_tracker::pipeline::{Pipeline, PipelineError, PipelineFrame, Scan};
use formation_tracker::rig::RigModel;
use formation_tracker::robots::RobotConfig;
use formation_tracker::tracker::{LeaderReport, SmoothedLeader, Tracker, TrackerConfig};
use pose::Camera;
use pose::PoseSolver;
use serde::Serialize;
use unicycle::Inputs;

use super::CliError;

/// Track leader robots through a stream of camera frames.
///
/// INPUT is a folder of PNG/JPEG images (sorted by name), a y4m file, `-` for a y4m stream
/// on stdin (e.g. `ffmpeg -i video.mp4 -f yuv4mpegpipe -pix_fmt yuv420p - | formation-tracker
/// track - --camera cam.yaml`), or a ROS 2 bag: a rosbag2 `.mcap` file or folder, whose images,
/// CameraInfo and odometry are used as recorded (docs/bags.md). Prints one line per frame on
/// stdout (JSON with --json); --mcap also writes a file that opens in Foxglove.
#[derive(Debug, ClapArgs)]
pub struct Args {
    /// A folder of images, a y4m file, `-` for y4m on stdin, or a ROS 2 bag (.mcap file or
    /// rosbag2 folder).
    #[arg(value_name = "INPUT")]
    pub(super) input: PathBuf,
    /// Camera calibration (OpenCV YAML or ROS camera_info); for a bag, default: its
    /// CameraInfo.
    #[arg(long, value_name = "FILE")]
    pub(super) camera: Option<PathBuf>,
    /// Bag input: the image topic (sensor_msgs/msg/Image or CompressedImage); default: the
    /// bag's only image topic.
    #[arg(long, value_name = "TOPIC")]
    pub(super) image_topic: Option<String>,
    /// Bag input: the follower's inputs topic (nav_msgs/msg/Odometry, geometry_msgs/msg/Twist
    /// or TwistStamped); default: the bag's only one (Odometry first). --inputs CSV wins.
    #[arg(long, value_name = "TOPIC")]
    pub(super) inputs_topic: Option<String>,
    /// Also write the results as MCAP for Foxglove: images, marker and rig annotations,
    /// camera-to-leader transforms and the formation estimate (docs/outputs.md).
    #[arg(long, value_name = "OUT.mcap")]
    pub(super) mcap: Option<PathBuf>,
    /// With --mcap: leave the images out (annotations, transforms and estimates only).
    #[arg(long, requires = "mcap")]
    pub(super) no_images: bool,
    /// Rig file (YAML/JSON); default: the reference rig.
    #[arg(long, value_name = "FILE")]
    pub(super) rig: Option<PathBuf>,
    /// Follower inputs per frame: CSV with `frame` or `t`, `v2`, `w2`, optional `pan`.
    #[arg(long, value_name = "CSV")]
    pub(super) inputs: Option<PathBuf>,
    /// Frame rate, 0.001 to 10000 frames/s; default: the y4m header's, else 30.
    #[arg(long, value_name = "F", value_parser = super::numbers::fps)]
    pub(super) fps: Option<f64>,
    /// One JSON object per frame instead of a text line.
    #[arg(long)]
    pub(super) json: bool,
    /// Camera offset ahead of the follower's axle, metres (the paper's d), 0 to 100.
    #[arg(long, value_name = "M", default_value_t = CameraMount::default().offset,
          value_parser = super::numbers::offset, allow_hyphen_values = true)]
    pub(super) mount_offset: f64,
    /// Camera height above the ground, metres, above 0 and below 100.
    #[arg(long, value_name = "M", default_value_t = CameraMount::default().height,
          value_parser = super::numbers::height, allow_hyphen_values = true)]
    pub(super) mount_height: f64,
    /// Camera tilt below the horizontal, radians, between -pi/2 and pi/2.
    #[arg(long, value_name = "RAD", default_value_t = 0.0,
          value_parser = super::numbers::tilt, allow_hyphen_values = true)]
    pub(super) mount_tilt: f64,
    /// Camera pan (left positive), radians, between -pi and pi, when the inputs CSV has no
    /// `pan` column.
    #[arg(long, value_name = "RAD", default_value_t = 0.0,
          value_parser = super::numbers::angle, allow_hyphen_values = true)]
    pub(super) pan: f64,
    /// Accept frames whose size differs from the calibration's by scaling the intrinsics
    /// (frames resized from the calibrated camera's, same aspect ratio). Without it such
    /// frames are errors: their poses would be wrong by the scale.
    #[arg(long = "scale-calibration")]
    pub(super) scale_calibration: bool,
    /// Largest image side accepted, pixels; larger frames are refused from their header,
    /// before they are decoded.
    #[arg(long, value_name = "PX", default_value_t = formation_io::frames::MAX_SIDE,
          value_parser = super::numbers::max_side)]
    pub(super) max_side: usize,
    /// Seconds without a measurement before a track is dropped.
    #[arg(long, value_name = "S", default_value_t = 2.0, value_parser = super::numbers::positive)]
    pub(super) lost_after: f64,
    /// After the causal pass, smooth every track over the whole recording (fixed-interval
    /// unscented RTS smoother, docs/smoothing.md) and print one more line per frame and
    /// leader (`"smoothed": true` with --json; see docs/outputs.md). Keeps every filter step
    /// in memory until the end.
    #[arg(long)]
    pub(super) smooth: bool,
    /// Tracking-guided detection: search only where the tracker predicts each leader's rig
    /// (with a margin from the prediction's uncertainty), and scan the whole frame every
    /// --full-scan-every frames, when a track coasts and while nothing is tracked. Much
    /// faster on large frames (docs/tracking.md, docs/performance.md).
    #[arg(long)]
    pub(super) guided: bool,
    /// With --guided: a full-frame scan at least every N frames, so that robots entering
    /// the view are picked up within N frames.
    #[arg(long, value_name = "N", requires = "guided", default_value_t = GuidedConfig::default().full_scan_period,
          value_parser = clap::value_parser!(u32).range(1..))]
    pub(super) full_scan_every: u32,
    /// Also search large dark regions that gave no quad by AprilTag 3's boundary
    /// clustering, as `detect` does by default: reads markers that touch something as dark
    /// as their ink (a rig's tag against a dark floor or a shadow). Off by default in
    /// `track`: it costs about 3 ms more per 640x480 real frame, and 2-4x the detection
    /// time on cluttered frames (docs/marker-families.md).
    #[arg(long)]
    pub(super) boundary_clusters: bool,
}

#[derive(Serialize)]
struct Line<'a> {
    frame: u64,
    /// Bag input only: where the frame came from in the bag, and the time gaps before it.
    #[serde(flatten, skip_serializing_if = "Option::is_none")]
    bag: Option<BagLine>,
    /// Where the frame came from: the image file, or `INPUT#N` for frame N of a y4m stream.
    source: &'a str,
    t: f64,
    leaders: &'a [LeaderReport],
    markers: usize,
    failures: &'a [String],
    timing: TimingOut,
    scan: Scan,
}

/// The bag fields of a JSON line (`docs/outputs.md`).
#[derive(Debug, Clone, Copy, Serialize)]
pub(super) struct BagLine {
    /// The message's `header.stamp`, nanoseconds since the epoch.
    pub(super) stamp_ns: u64,
    /// The message's index on the image topic, from 0, in file order.
    pub(super) message: u64,
    /// Frames missing just before this one (a gap of about n frame periods counts n - 1).
    pub(super) missing_before: u64,
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
    refuse_overwriting_inputs(args)?;
    super::interrupt::install()?;
    if formation_io::bag::is_bag(&args.input) {
        return super::track_bag::run(args);
    }
    if args.image_topic.is_some() || args.inputs_topic.is_some() {
        return Err(super::Usage(
            "--image-topic and --inputs-topic are for bag input (.mcap)".into(),
        )
        .into());
    }
    let camera = args.camera.as_ref().ok_or_else(|| {
        super::Usage(
            "--camera FILE is required for image folders and y4m input (a bag can give its own CameraInfo)"
                .into(),
        )
    })?;
    let calibration = super::load_calibration(camera)?;
    let dict = Dictionary::paper();
    let rig = super::load_rig(args.rig.as_deref(), dict)?;
    let mut frames = FrameSource::open_with_max_side(&args.input, args.max_side)?;
    let fps = frame_rate(args, &frames)?;
    let inputs = match &args.inputs {
        Some(path) => Some(FollowerInputs::from_path(path)?),
        None => {
            super::progress::errln!(
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
    let mut mcap: Option<super::track_bag::McapOut> = None;
    loop {
        if super::interrupt::requested().is_some() {
            break;
        }
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
                if let Some(path) = &args.mcap {
                    mcap = Some(super::track_bag::McapOut::create(
                        path,
                        args,
                        rig.clone(),
                        calibration,
                    )?);
                }
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
                write_frame(&mut out, args.json, index, &source, t, &done, None)?;
                if let Some(writer) = &mut mcap {
                    // Folders and y4m have no stamps: t from 0.
                    let stamp_ns = (t * 1e9).round() as u64;
                    writer.frame(index, stamp_ns, t, image, &done, pipeline.markers())?;
                }
            }
            Err(e) => {
                broken += 1;
                progress.println(&super::track::frame_error(index, &e));
            }
        }
    }
    if args.smooth
        && let Some(pipeline) = &pipeline
    {
        write_smoothed(&mut out, args.json, pipeline.tracker(), |t| {
            (t * fps).round() as u64
        })?;
    }
    out.flush().map_err(super::StdoutError)?;
    progress.finish();
    if let Some(w) = mcap {
        w.finish(processed > 0)?;
    }
    super::interrupt::stopped(|| {
        format!("{processed} frames tracked and written, {broken} broken")
    })?;
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
    super::progress::errln!("track: {summary}");
    Ok(())
}

/// Refuses, before any work, an `--mcap` output that is one of the inputs (exit code 2).
fn refuse_overwriting_inputs(args: &Args) -> Result<(), CliError> {
    let Some(mcap) = &args.mcap else {
        return Ok(());
    };
    let mut inputs: Vec<(&str, &std::path::Path)> = vec![("INPUT", &args.input)];
    for (name, path) in [
        ("--camera", &args.camera),
        ("--rig", &args.rig),
        ("--inputs", &args.inputs),
    ] {
        if let Some(path) = path {
            inputs.push((name, path));
        }
    }
    super::output::refuse_inputs_as_outputs(&[("--mcap", mcap)], &inputs)
}

/// The line for a frame the pipeline could not use, with a hint when the frame's size is
/// not the calibration's (folders, y4m and bags alike).
pub(super) fn frame_error(index: u64, e: &PipelineError) -> String {
    let hint = if matches!(e, PipelineError::SizeMismatch { .. }) {
        " (pass --scale-calibration if the frames were resized from the calibrated camera's)"
    } else {
        ""
    };
    format!("track: frame {index}: {e}{hint}")
}

/// `--fps`, else the stream's own rate, else 30 (said on stderr).
fn frame_rate(args: &Args, frames: &FrameSource) -> Result<f64, CliError> {
    let fps = match (args.fps, frames.frame_rate()) {
        (Some(f), _) => f,
        (None, Some(f)) => f,
        (None, None) => {
            super::progress::errln!(
                "track: no --fps and no frame rate in the input: assuming 30 frames/s"
            );
            30.0
        }
    };
    Ok(super::numbers::check_fps(fps).map_err(|e| format!("the input's frame rate: {e}"))?)
}

/// The detector, the calibrated solver, the rig and the tracker, in one pipeline.
pub(super) fn build_pipeline(
    args: &Args,
    calibration: Camera,
    rig: RigModel,
    mount: CameraMount,
    fps: f64,
) -> Result<Pipeline, CliError> {
    let mut config = TrackerConfig::reference(mount.offset, 1.0 / fps);
    config.lost_after = args.lost_after;
    let mut tracker = Tracker::new(config)?;
    tracker.record_history(args.smooth);
    let solver = PoseSolver::new(calibration.intrinsics).with_distortion(calibration.distortion);
    // The rig's dictionary: our own unless the rig file names another (e.g. tag36h11).
    let dictionary = rig.marker_dictionary()?.clone();
    let mut pipeline = Pipeline::new(
        Detector::with_dictionary(
            DetectorConfig {
                boundary_clusters: args.boundary_clusters,
                ..DetectorConfig::default()
            },
            dictionary,
        ),
        solver,
        (calibration.width, calibration.height),
        rig,
        RobotConfig::default(),
        tracker,
    );
    if args.guided {
        pipeline.set_guided(Some(GuidedConfig {
            full_scan_period: args.full_scan_every,
            ..GuidedConfig::default()
        }))?;
    }
    Ok(pipeline)
}

/// A smoothed leader's line with `--json`.
#[derive(Serialize)]
struct SmoothedLine<'a> {
    smoothed: bool,
    frame: u64,
    #[serde(flatten)]
    leader: &'a SmoothedLeader,
}

/// `--smooth`: the smoothed estimates of every track, one line per frame and leader,
/// in track-segment order, after the causal lines; `frame_of` gives the frame number of a
/// time handed to the tracker.
pub(super) fn write_smoothed(
    out: &mut impl Write,
    json: bool,
    tracker: &Tracker,
    frame_of: impl Fn(f64) -> u64,
) -> Result<(), CliError> {
    let smoothed = tracker
        .smooth()
        .map_err(|e| format!("track --smooth: the smoother failed: {e}"))?;
    let mut text = String::new();
    for l in &smoothed {
        let frame = frame_of(l.t);
        if json {
            let line = SmoothedLine {
                smoothed: true,
                frame,
                leader: l,
            };
            text += &serde_json::to_string(&line)?;
            text.push('\n');
        } else {
            use std::fmt::Write as _;
            writeln!(
                text,
                "smoothed frame {frame} t {:.3}: robot {} l12 {:.3} alpha12 {:.3} beta12 {:.3} v1 {:.2} w1 {:.2}{}",
                l.t,
                l.robot,
                l.l12,
                l.alpha12,
                l.beta12,
                l.v1,
                l.w1,
                if l.measured { "" } else { " (not measured)" }
            )?;
        }
    }
    out.write_all(text.as_bytes()).map_err(super::StdoutError)?;
    Ok(())
}

/// One frame's line: JSON with `--json`, else text; flushed, so that a reader of a live
/// stream gets each frame as it is done.
#[allow(clippy::too_many_arguments)]
pub(super) fn write_frame(
    out: &mut impl Write,
    json: bool,
    index: u64,
    source: &str,
    t: f64,
    done: &PipelineFrame,
    bag: Option<BagLine>,
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
            bag,
            source,
            t,
            leaders: &done.report.leaders,
            markers: done.markers,
            failures: &done.failures,
            timing,
            scan: done.scan,
        };
        out.write_all(format!("{}\n", serde_json::to_string(&line)?).as_bytes())
            .and_then(|()| out.flush())
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
    // Each frame's line goes out as it is done (`track - | jq` on a live stream).
    out.write_all(text.as_bytes())
        .and_then(|()| out.flush())
        .map_err(super::StdoutError)?;
    Ok(())
}
