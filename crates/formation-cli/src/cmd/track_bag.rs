//! `formation-tracker track BAG`: the `track` loop over a ROS 2 bag (images, CameraInfo and
//! the follower's inputs as recorded, each frame at its `header.stamp`), and the `--mcap`
//! output shared with the other inputs.

use std::io::Write;
use std::path::{Path, PathBuf};

use fiducial::Dictionary;
use formation_io::bag::{Bag, BagError};
use formation_io::foxglove::{FoxgloveWriter, FrameOut};
use formation_io::frames::GreyImage;
use formation_io::inputs::FollowerInputs;
use formation_tracker::mount::CameraMount;
use formation_tracker::pipeline::{Pipeline, PipelineFrame};
use formation_tracker::rig::RigModel;
use formation_tracker::robots::MarkerObservation;
use pose::Camera;
use unicycle::Inputs;

use super::CliError;
use super::track::{Args, BagLine, build_pipeline, write_frame, write_smoothed};

/// The `--mcap` output file.
#[derive(Debug)]
pub struct McapOut {
    path: PathBuf,
    writer: FoxgloveWriter<std::io::BufWriter<std::fs::File>>,
    images: bool,
    /// The file under its temporary name until [`Self::finish`] keeps it.
    staged: super::output::Staged,
}

impl McapOut {
    /// Creates the file.
    pub fn create(
        path: &Path,
        args: &Args,
        rig: RigModel,
        calibration: Camera,
    ) -> Result<Self, CliError> {
        super::prepare_out_file(path)?;
        let mut staged = super::output::Staged::new();
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

/// Runs `track` on a bag.
pub fn run(args: &Args) -> Result<(), CliError> {
    let bag = Bag::open(&args.input)?;
    let image_topic = bag.image_topic(args.image_topic.as_deref())?;
    let calibration = match &args.camera {
        Some(path) => super::load_calibration(path)?,
        None => {
            let topic = bag.camera_info_topic(&image_topic)?;
            let c = bag.calibration(&topic)?;
            super::progress::errln!("track: calibration from {topic} ({}x{})", c.width, c.height);
            c
        }
    };
    let dict = Dictionary::paper();
    let rig = super::load_rig(args.rig.as_deref(), dict)?;
    let csv = args
        .inputs
        .as_ref()
        .map(|p| FollowerInputs::from_path(p))
        .transpose()?;
    let inputs_topic = if csv.is_some() {
        None
    } else {
        bag.inputs_topic(args.inputs_topic.as_deref())?
    };
    match (&csv, &inputs_topic) {
        (None, None) => super::progress::errln!(
            "track: no --inputs and no odometry or twist topic in the bag: assuming the follower \
             stands still (v2 = w2 = 0, pan {})",
            args.pan
        ),
        (None, Some(topic)) => super::progress::errln!("track: follower inputs from {topic}"),
        _ => {}
    }
    let mut frames = bag.frames(&image_topic, inputs_topic.as_deref(), args.max_side);
    let mount = CameraMount {
        offset: args.mount_offset,
        height: args.mount_height,
        pan: args.pan,
        tilt: args.mount_tilt,
    };
    let mut pipeline: Option<Pipeline> = None;
    let mut mcap: Option<McapOut> = None;
    let mut progress = super::progress::Progress::new("track", "frames", frames.len_hint());
    let stdout = std::io::stdout();
    let mut out = std::io::BufWriter::new(stdout.lock());
    let (mut broken, mut processed, mut bad_inputs) = (0u64, 0u64, 0u64);
    let mut first_stamp: Option<u64> = None;
    let mut fatal: Option<BagError> = None;
    // With --smooth: each processed frame's time and number, in time order (stamps are
    // reordered by the reader), so that the smoothed lines name the same frames.
    let mut frame_times: Vec<(f64, u64)> = Vec::new();
    loop {
        if super::interrupt::requested().is_some() {
            break;
        }
        let frame = match frames.next_frame() {
            Ok(Some(frame)) => frame,
            Ok(None) => break,
            Err(e) if e.is_fatal() => {
                // Reported once, at the end; frames already read are still handed out.
                fatal = Some(e);
                continue;
            }
            Err(e) => {
                progress.println(&format!("track: {e}"));
                // A bad input message leaves the previous inputs in force; a bad image
                // message is a broken frame.
                match &e {
                    BagError::Message { topic, .. } if *topic != image_topic => bad_inputs += 1,
                    _ => broken += 1,
                }
                continue;
            }
        };
        progress.inc();
        let first = *first_stamp.get_or_insert(frame.stamp_ns);
        let t = (frame.stamp_ns - first) as f64 * 1e-9;
        let index = frame.index;
        let (follower, pan) = match &csv {
            Some(csv) => match csv.at(index, t) {
                Some(s) => (s.inputs, s.pan.unwrap_or(args.pan)),
                None => (Inputs::new(0.0, 0.0), args.pan),
            },
            None => (frame.inputs.unwrap_or(Inputs::new(0.0, 0.0)), args.pan),
        };
        let image = frame.image;
        let message = frame.message;
        let stamp_ns = frame.stamp_ns;
        let pipeline = match &mut pipeline {
            Some(p) => p,
            None => {
                let calibration = if args.scale_calibration {
                    calibration.scaled_to(image.width as u32, image.height as u32)?
                } else {
                    calibration
                };
                let fps = bag_fps(args, frame.period_s)?;
                if let Some(path) = &args.mcap {
                    mcap = Some(McapOut::create(path, args, rig.clone(), calibration)?);
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
                if args.smooth {
                    frame_times.push((t, index));
                }
                let source = format!("{}#{message}", image_topic);
                let bag_line = BagLine {
                    stamp_ns,
                    message,
                    missing_before: frame.missing_before,
                };
                write_frame(
                    &mut out,
                    args.json,
                    index,
                    &source,
                    t,
                    &done,
                    Some(bag_line),
                )?;
                if let Some(w) = &mut mcap {
                    w.frame(index, stamp_ns, t, image, &done, pipeline.markers())?;
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
            frame_of(&frame_times, t)
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
    let s = frames.stats();
    let mut summary = format!(
        "{processed} frames tracked, {broken} broken; bag: {} image messages, {} reordered, {} out of order (dropped), {} missing, {} irregular intervals, {} late input messages, {bad_inputs} unreadable input messages",
        s.messages, s.reordered, s.out_of_order_dropped, s.dropped, s.irregular, s.late_inputs
    );
    if let Some(e) = &fatal {
        summary.push_str(&format!("; stopped: {e}"));
    }
    let missing = bag.missing_files();
    if !missing.is_empty() {
        let names: Vec<String> = missing.iter().map(|p| p.display().to_string()).collect();
        summary.push_str(&format!(
            "; {} split file(s) listed in metadata.yaml are missing: {}",
            missing.len(),
            names.join(", ")
        ));
    }
    if processed == 0 {
        return Err(match fatal {
            Some(e) => e.into(),
            None => format!("nothing tracked: {summary}").into(),
        });
    }
    if broken > 0
        || bad_inputs > 0
        || fatal.is_some()
        || s.out_of_order_dropped > 0
        || !missing.is_empty()
    {
        return Err(super::Partial(summary).into());
    }
    super::progress::errln!("track: {summary}");
    Ok(())
}

/// `--fps`, else the bag's nominal frame rate (from its stamps), else 30 (said on stderr).
fn bag_fps(args: &Args, period_s: Option<f64>) -> Result<f64, CliError> {
    let fps = match (args.fps, period_s) {
        (Some(f), _) => f,
        // Stamps are whole nanoseconds, so 30 frames/s comes out as 29.99999997: the rate
        // is rounded to 0.001 frames/s, as a frame rate is written.
        (None, Some(p)) => (1.0 / p * 1000.0).round() / 1000.0,
        (None, None) => {
            super::progress::errln!(
                "track: no --fps and a single frame in the bag: assuming 30 frames/s"
            );
            30.0
        }
    };
    Ok(super::numbers::check_fps(fps).map_err(|e| format!("the bag's frame rate: {e}"))?)
}

/// The number of the processed frame whose time is nearest `t` (`times` in time order).
fn frame_of(times: &[(f64, u64)], t: f64) -> u64 {
    let i = times.partition_point(|&(ft, _)| ft < t);
    let near = |j: usize| times.get(j).map(|&(ft, n)| ((ft - t).abs(), n));
    match (i.checked_sub(1).and_then(near), near(i)) {
        (Some((da, a)), Some((db, b))) => {
            if da <= db {
                a
            } else {
                b
            }
        }
        (Some((_, n)), None) | (None, Some((_, n))) => n,
        (None, None) => 0,
    }
}

#[cfg(test)]
mod tests {
    use super::frame_of;

    #[test]
    fn smoothed_times_map_to_the_nearest_processed_frame() {
        // Frame 2 was dropped; stamps are irregular.
        let times = [(0.0, 0), (0.033, 1), (0.1, 3), (0.134, 4)];
        assert_eq!(frame_of(&times, 0.0), 0);
        assert_eq!(frame_of(&times, 0.033), 1);
        assert_eq!(frame_of(&times, 0.1), 3);
        assert_eq!(frame_of(&times, 0.1339999), 4);
        assert_eq!(frame_of(&times, 9.0), 4);
        assert_eq!(frame_of(&[], 1.0), 0);
    }
}
