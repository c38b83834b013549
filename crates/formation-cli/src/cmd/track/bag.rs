//! `track` on a ROS 2 bag: its images, CameraInfo and odometry as recorded (docs/bags.md).

use formation_io::bag::{Bag, BagError, BagStats};
use formation_io::inputs::FollowerInputs;
use pose::Camera;
use unicycle::Inputs;

use super::args::Args;
use super::session::{BagLine, FrameIn, Session};
use crate::cmd::{self, CliError, progress::errln};

/// Runs `track` on a bag.
pub fn run(args: &Args) -> Result<(), CliError> {
    let Sources {
        bag,
        image_topic,
        calibration,
        csv,
        inputs_topic,
    } = open(args)?;
    let mut frames = bag.frames(&image_topic, inputs_topic.as_deref(), args.run.max_side);
    let mut session = Session::new(&args.run, calibration, frames.len_hint())?;
    let (mut bad_inputs, mut first_stamp, mut fatal) = (0u64, None, None);
    // With --smooth: each processed frame's time and number, in time order (stamps are
    // reordered by the reader), so that the smoothed lines name the same frames.
    let mut frame_times: Vec<(f64, u64)> = Vec::new();
    while cmd::interrupt::requested().is_none() {
        let frame = match frames.next_frame() {
            Ok(Some(frame)) => frame,
            Ok(None) => break,
            Err(e) if e.is_fatal() => {
                // Reported once, at the end; frames already read are still handed out.
                fatal = Some(e);
                continue;
            }
            Err(e) => {
                session.progress.println(&format!("track: {e}"));
                // A bad input message leaves the previous inputs in force; a bad image
                // message is a broken frame.
                match &e {
                    BagError::Message { topic, .. } if *topic != image_topic => bad_inputs += 1,
                    _ => session.broken += 1,
                }
                continue;
            }
        };
        session.progress.inc();
        let first = *first_stamp.get_or_insert(frame.stamp_ns);
        let t = (frame.stamp_ns - first) as f64 * 1e-9;
        let index = frame.index;
        let (follower, pan) = match &csv {
            Some(csv) => match csv.at(index, t) {
                Some(s) => (s.inputs, s.pan.unwrap_or(args.run.pan)),
                None => (Inputs::new(0.0, 0.0), args.run.pan),
            },
            None => (frame.inputs.unwrap_or(Inputs::new(0.0, 0.0)), args.run.pan),
        };
        let bag_line = BagLine {
            stamp_ns: frame.stamp_ns,
            message: frame.message,
            missing_before: frame.missing_before,
        };
        let input = FrameIn {
            index,
            source: format!("{}#{}", image_topic, frame.message),
            t,
            follower,
            pan,
            image: frame.image,
            stamp_ns: frame.stamp_ns,
            bag: Some(bag_line),
        };
        let period_s = frame.period_s;
        if session.frame(input, || bag_fps(args, period_s))?.is_some() && args.run.smooth {
            frame_times.push((t, index));
        }
    }
    let (processed, broken) = session.finish(|t| frame_of(&frame_times, t))?;
    let missing = bag.missing_files();
    outcome(
        processed,
        broken,
        bad_inputs,
        &frames.stats(),
        fatal,
        missing,
    )
}

/// The bag, its topics, the calibration and the follower's inputs of a run.
struct Sources {
    bag: Bag,
    image_topic: String,
    calibration: Camera,
    csv: Option<FollowerInputs>,
    inputs_topic: Option<String>,
}

/// Opens the bag and finds what the run reads: the image topic, the calibration (`--camera`,
/// else the bag's CameraInfo) and the follower's inputs (`--inputs`, else the bag's odometry
/// or twist topic, else standing still), each said on stderr when taken from the bag.
fn open(args: &Args) -> Result<Sources, CliError> {
    let bag = Bag::open(&args.input)?;
    let image_topic = bag.image_topic(args.image_topic.as_deref())?;
    let calibration = match &args.camera {
        Some(path) => cmd::load_calibration(path)?,
        None => {
            let topic = bag.camera_info_topic(&image_topic)?;
            let c = bag.calibration(&topic)?;
            errln!("track: calibration from {topic} ({}x{})", c.width, c.height);
            c
        }
    };
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
        (None, None) => errln!(
            "track: no --inputs and no odometry or twist topic in the bag: assuming the follower \
             stands still (v2 = w2 = 0, pan {})",
            args.run.pan
        ),
        (None, Some(topic)) => errln!("track: follower inputs from {topic}"),
        _ => {}
    }
    Ok(Sources {
        bag,
        image_topic,
        calibration,
        csv,
        inputs_topic,
    })
}

/// The run's result from its counts: an error when nothing was tracked, a partial result
/// (exit code 3) when anything was lost, else the summary on stderr.
fn outcome(
    processed: u64,
    broken: u64,
    bad_inputs: u64,
    stats: &BagStats,
    fatal: Option<BagError>,
    missing: &[std::path::PathBuf],
) -> Result<(), CliError> {
    let summary = summary(
        processed,
        broken,
        bad_inputs,
        stats,
        fatal.as_ref(),
        missing,
    );
    if processed == 0 {
        return Err(match fatal {
            Some(e) => e.into(),
            None => format!("nothing tracked: {summary}").into(),
        });
    }
    if broken > 0
        || bad_inputs > 0
        || fatal.is_some()
        || stats.out_of_order_dropped > 0
        || !missing.is_empty()
    {
        return Err(cmd::Partial(summary).into());
    }
    errln!("track: {summary}");
    Ok(())
}

/// The last line of a bag run: what was tracked, what the bag held, what went wrong.
fn summary(
    processed: u64,
    broken: u64,
    bad_inputs: u64,
    s: &BagStats,
    fatal: Option<&BagError>,
    missing: &[std::path::PathBuf],
) -> String {
    let mut summary = format!(
        "{processed} frames tracked, {broken} broken; bag: {} image messages, {} reordered, {} out of order (dropped), {} missing, {} irregular intervals, {} late input messages, {bad_inputs} unreadable input messages",
        s.messages, s.reordered, s.out_of_order_dropped, s.dropped, s.irregular, s.late_inputs
    );
    if let Some(e) = fatal {
        summary.push_str(&format!("; stopped: {e}"));
    }
    if !missing.is_empty() {
        let names: Vec<String> = missing.iter().map(|p| p.display().to_string()).collect();
        summary.push_str(&format!(
            "; {} split file(s) listed in metadata.yaml are missing: {}",
            missing.len(),
            names.join(", ")
        ));
    }
    summary
}

/// `--fps`, else the bag's nominal frame rate (from its stamps), else 30 (said on stderr).
fn bag_fps(args: &Args, period_s: Option<f64>) -> Result<f64, CliError> {
    let fps = match (args.fps, period_s) {
        (Some(f), _) => f,
        // Stamps are whole nanoseconds, so 30 frames/s comes out as 29.99999997: the rate
        // is rounded to 0.001 frames/s, as a frame rate is written.
        (None, Some(p)) => (1.0 / p * 1000.0).round() / 1000.0,
        (None, None) => {
            errln!("track: no --fps and a single frame in the bag: assuming 30 frames/s");
            30.0
        }
    };
    Ok(cmd::numbers::check_fps(fps).map_err(|e| format!("the bag's frame rate: {e}"))?)
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
