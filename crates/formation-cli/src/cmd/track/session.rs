//! What every `track` run shares, whatever its input: the pipeline, the per-frame lines on
//! stdout, the `--smooth` lines and the `--mcap` file.

use std::io::Write;
use std::path::{Path, PathBuf};

use fiducial::{Detector, DetectorConfig, Dictionary};
use formation_io::foxglove::{FoxgloveWriter, FrameOut};
use formation_io::frames::GreyImage;
use formation_tracker::guided::GuidedConfig;
use formation_tracker::mount::CameraMount;
use formation_tracker::pipeline::{Pipeline, PipelineError, PipelineFrame, Scan};
use formation_tracker::rig::RigModel;
use formation_tracker::robots::{MarkerObservation, RobotConfig};
use formation_tracker::tracker::{LeaderReport, SmoothedLeader, Tracker, TrackerConfig};
use pose::{Camera, PoseSolver};
use serde::Serialize;
use unicycle::Inputs;

use super::args::RunArgs as Args;
use crate::cmd::{self, CliError, progress::Progress};

/// One frame for [`Session::frame`], wherever it came from.
pub struct FrameIn<'a> {
    /// Frame number.
    pub index: u64,
    /// Where it came from: the image file, `INPUT#N` (y4m) or `TOPIC#N` (bag).
    pub source: String,
    /// Time handed to the tracker, seconds from the first frame.
    pub t: f64,
    /// The follower's inputs and camera pan at this frame.
    pub follower: Inputs,
    /// Camera pan, radians.
    pub pan: f64,
    /// The grey image.
    pub image: &'a GreyImage,
    /// Stamp for the `--mcap` file, nanoseconds.
    pub stamp_ns: u64,
    /// The bag fields of the JSON line (bag input only).
    pub bag: Option<BagLine>,
}

/// What every `track` run shares, whatever the input: the pipeline (built at the first frame,
/// whose size the calibration is scaled to with `--scale-calibration`), the stdout lines,
/// the `--mcap` file, the progress and the counts.
pub struct Session<'a> {
    args: &'a Args,
    calibration: Camera,
    rig: RigModel,
    mount: CameraMount,
    pipeline: Option<Pipeline>,
    /// The follower's own controller (`--controller`), and the set-points last told.
    own: Option<(
        formation_io::controller::FollowerController,
        unicycle::ControllerConfig,
    )>,
    mcap: Option<McapOut>,
    out: std::io::BufWriter<std::io::StdoutLock<'static>>,
    /// The progress line (also where per-frame errors are printed).
    pub progress: Progress,
    /// Frames tracked and written.
    pub processed: u64,
    /// Frames that could not be used.
    pub broken: u64,
}

impl<'a> Session<'a> {
    /// A session with `calibration` and the rig of `--rig` (or the reference rig).
    pub fn new(
        args: &'a Args,
        calibration: Camera,
        len_hint: Option<u64>,
    ) -> Result<Self, CliError> {
        let rig = cmd::load_rig(args.rig.as_deref(), Dictionary::paper())?;
        let own = match &args.controller {
            Some(path) => {
                let own = formation_io::controller::load(path)?;
                let first = own.at(0.0);
                Some((own, first))
            }
            None => None,
        };
        Ok(Self {
            own,
            args,
            calibration,
            rig,
            mount: CameraMount {
                offset: args.mount_offset,
                height: args.mount_height,
                pan: args.pan,
                tilt: args.mount_tilt,
            },
            pipeline: None,
            mcap: None,
            out: std::io::BufWriter::new(std::io::stdout().lock()),
            progress: Progress::new("track", "frames", len_hint),
            processed: 0,
            broken: 0,
        })
    }

    /// Tracks one frame and writes its line (and its `--mcap` messages); `fps` gives the
    /// frame rate when the pipeline is built, at the first frame. Returns the tracked
    /// frame, or `None` for a frame the pipeline cannot use (counted and reported).
    pub fn frame(
        &mut self,
        f: FrameIn<'_>,
        fps: impl FnOnce() -> Result<f64, CliError>,
    ) -> Result<Option<PipelineFrame>, CliError> {
        let (args, image) = (self.args, f.image);
        let pipeline = match &mut self.pipeline {
            Some(pipeline) => pipeline,
            None => {
                let calibration = if args.scale_calibration {
                    self.calibration
                        .scaled_to(image.width as u32, image.height as u32)?
                } else {
                    self.calibration
                };
                let fps = fps()?;
                if let Some(path) = &args.mcap {
                    self.mcap = Some(McapOut::create(path, args, self.rig.clone(), calibration)?);
                }
                let mut built =
                    build_pipeline(args, calibration, self.rig.clone(), self.mount, fps)?;
                if let Some((own, told)) = &self.own {
                    built
                        .tracker_mut()
                        .set_follower_controller(own.leader, Some(*told));
                }
                self.pipeline.insert(built)
            }
        };
        let mount = CameraMount {
            pan: f.pan,
            ..self.mount
        };
        // A set-point change of the controller file, told from its time on.
        if let Some((own, told)) = &mut self.own {
            let now = own.at(f.t);
            if now != *told {
                *told = now;
                pipeline
                    .tracker_mut()
                    .set_follower_controller(own.leader, Some(now));
            }
        }
        match pipeline.process(
            &image.data,
            image.width,
            image.height,
            f.t,
            f.follower,
            mount,
        ) {
            Ok(done) => {
                self.processed += 1;
                write_frame(
                    &mut self.out,
                    args.json,
                    f.index,
                    &f.source,
                    f.t,
                    &done,
                    f.bag,
                )?;
                if let Some(w) = &mut self.mcap {
                    w.frame(f.index, f.stamp_ns, f.t, image, &done, pipeline.markers())?;
                }
                Ok(Some(done))
            }
            Err(e) => {
                self.broken += 1;
                self.progress.println(&frame_error(f.index, &e));
                Ok(None)
            }
        }
    }

    /// The pipeline, once the first frame has built it.
    pub fn pipeline(&self) -> Option<&Pipeline> {
        self.pipeline.as_ref()
    }

    /// The camera's mount (its pan as given on the command line).
    pub fn mount(&self) -> CameraMount {
        self.mount
    }

    /// Ends the run: the `--smooth` lines (`frame_of` gives the frame number of a time
    /// handed to the tracker), stdout flushed, the `--mcap` file kept if anything was
    /// tracked, and the interruption reported if there was one.
    pub fn finish(mut self, frame_of: impl Fn(f64) -> u64) -> Result<(u64, u64), CliError> {
        if self.args.smooth
            && let Some(pipeline) = &self.pipeline
        {
            write_smoothed(&mut self.out, self.args.json, pipeline.tracker(), frame_of)?;
        }
        self.out.flush().map_err(cmd::StdoutError)?;
        self.progress.finish();
        let (processed, broken) = (self.processed, self.broken);
        if let Some(w) = self.mcap {
            w.finish(processed > 0)?;
        }
        cmd::interrupt::stopped(|| {
            format!("{processed} frames tracked and written, {broken} broken")
        })?;
        Ok((processed, broken))
    }
}

/// The `--mcap` output file.
#[derive(Debug)]
pub struct McapOut {
    path: PathBuf,
    writer: FoxgloveWriter<std::io::BufWriter<std::fs::File>>,
    images: bool,
    /// The file under its temporary name until [`Self::finish`] keeps it.
    staged: cmd::output::Staged,
}

impl McapOut {
    /// Creates the file.
    pub fn create(
        path: &Path,
        args: &Args,
        rig: RigModel,
        calibration: Camera,
    ) -> Result<Self, CliError> {
        cmd::prepare_out_file(path)?;
        let mut staged = cmd::output::Staged::new();
        let file = staged.create(path)?;
        let writer = FoxgloveWriter::new(file, rig, calibration, !args.no_images)
            .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
        Ok(Self {
            path: path.to_path_buf(),
            writer,
            images: !args.no_images,
            staged,
        })
    }

    /// Writes one frame.
    pub fn frame(
        &mut self,
        frame: u64,
        stamp_ns: u64,
        t: f64,
        image: &GreyImage,
        result: &PipelineFrame,
        markers: &[MarkerObservation],
    ) -> Result<(), CliError> {
        let out = FrameOut {
            frame,
            stamp_ns,
            t,
            image: self
                .images
                .then_some((&image.data[..], image.width, image.height)),
            result,
            markers,
        };
        self.writer
            .frame(&out)
            .map_err(|e| format!("cannot write {}: {e}", self.path.display()).into())
    }

    /// Ends the file (summary and footer) and, if `keep`, renames it into place; without
    /// `keep` (nothing was tracked) it is removed and an earlier file of that name is left
    /// as it was.
    pub fn finish(self, keep: bool) -> Result<(), CliError> {
        self.writer
            .finish()
            .and_then(|mut w| w.flush())
            .map_err(|e| format!("cannot write {}: {e}", self.path.display()))?;
        if keep {
            self.staged.commit()?;
        }
        Ok(())
    }
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
pub struct BagLine {
    /// The message's `header.stamp`, nanoseconds since the epoch.
    pub stamp_ns: u64,
    /// The message's index on the image topic, from 0, in file order.
    pub message: u64,
    /// Frames missing just before this one (a gap of about n frame periods counts n - 1).
    pub missing_before: u64,
}

#[derive(Serialize)]
struct TimingOut {
    detect_ms: f64,
    pose_ms: f64,
    track_ms: f64,
    total_ms: f64,
}

/// The line for a frame the pipeline could not use, with a hint when the frame's size is
/// not the calibration's (folders, y4m and bags alike).
pub fn frame_error(index: u64, e: &PipelineError) -> String {
    let hint = if matches!(e, PipelineError::SizeMismatch { .. }) {
        " (pass --scale-calibration if the frames were resized from the calibrated camera's)"
    } else {
        ""
    };
    format!("track: frame {index}: {e}{hint}")
}

/// The detector, the calibrated solver, the rig and the tracker, in one pipeline.
pub fn build_pipeline(
    args: &Args,
    calibration: Camera,
    rig: RigModel,
    mount: CameraMount,
    fps: f64,
) -> Result<Pipeline, CliError> {
    let mut config = TrackerConfig::reference(mount.offset, 1.0 / fps);
    config.lost_after = args.lost_after;
    if let Some(noise) = args.odometry_noise {
        config.filter.tuning.input_noise_std = nalgebra::Vector2::from(noise);
    }
    let mut tracker = Tracker::new(config)?;
    tracker.record_history(args.smooth);
    let solver = PoseSolver::new(calibration.intrinsics).with_distortion(calibration.distortion);
    // The rig's dictionary: our own unless the rig file names another (e.g. tag36h11).
    let dictionary = rig.marker_dictionary()?.clone();
    let mut pipeline = Pipeline::new(
        Detector::with_dictionary(
            DetectorConfig {
                boundary_clusters: args.boundary_clusters,
                ..DetectorConfig::for_pose()
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
pub fn write_smoothed(
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
                l.formation.l12,
                l.formation.alpha12,
                l.formation.beta12,
                l.v1,
                l.w1,
                if l.measured { "" } else { " (not measured)" }
            )?;
        }
    }
    out.write_all(text.as_bytes()).map_err(cmd::StdoutError)?;
    Ok(())
}

/// One frame's line: JSON with `--json`, else text; flushed, so that a reader of a live
/// stream gets each frame as it is done.
#[allow(clippy::too_many_arguments)]
pub fn write_frame(
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
            .map_err(cmd::StdoutError)?;
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
            l.robot, l.status, l.formation.l12, l.formation.alpha12, l.formation.beta12, l.v1, l.w1
        )?;
    }
    writeln!(text, " ({:.1} ms)", timing.total_ms)?;
    // Each frame's line goes out as it is done (`track - | jq` on a live stream).
    out.write_all(text.as_bytes())
        .and_then(|()| out.flush())
        .map_err(cmd::StdoutError)?;
    Ok(())
}
