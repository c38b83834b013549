//! `track` on a folder of images, a y4m file or a y4m stream on stdin.

use formation_io::frames::FrameSource;
use formation_io::inputs::FollowerInputs;
use unicycle::Inputs;

use super::args::Args;
use super::session::{FrameIn, Session};
use crate::cmd::{self, CliError, progress::errln};

/// Runs `track` on frames (not a bag).
pub fn run(args: &Args) -> Result<(), CliError> {
    if args.image_topic.is_some() || args.inputs_topic.is_some() {
        return Err(cmd::Usage(
            "--image-topic and --inputs-topic are for bag input (.mcap)".into(),
        )
        .into());
    }
    let camera = args.camera.as_ref().ok_or_else(|| {
        cmd::Usage(
            "--camera FILE is required for image folders and y4m input (a bag can give its own CameraInfo)"
                .into(),
        )
    })?;
    let calibration = cmd::load_calibration(camera)?;
    let mut frames = FrameSource::open_with_max_side(&args.input, args.run.max_side)?;
    let fps = frame_rate(args, &frames)?;
    let inputs = match &args.inputs {
        Some(path) => Some(FollowerInputs::from_path(path)?),
        None => {
            errln!(
                "track: no --inputs: assuming the follower stands still (v2 = w2 = 0, pan {})",
                args.run.pan
            );
            None
        }
    };
    let mut session = Session::new(&args.run, calibration, frames.len_hint())?;
    while cmd::interrupt::requested().is_none() {
        let frame = match frames.next_frame() {
            Ok(Some(frame)) => frame,
            Ok(None) => break,
            Err(e) => {
                session.broken += 1;
                session.progress.println(&format!("track: {e}"));
                continue;
            }
        };
        session.progress.inc();
        let index = frame.index;
        let t = index as f64 / fps;
        let (follower, pan) = match inputs.as_ref().and_then(|i| i.at(index, t)) {
            Some(s) => (s.inputs, s.pan.unwrap_or(args.run.pan)),
            None => (Inputs::new(0.0, 0.0), args.run.pan),
        };
        let source = frame.file.map_or_else(
            || format!("{}#{index}", args.input.display()),
            |file| file.display().to_string(),
        );
        // Folders and y4m have no stamps: t from 0.
        let stamp_ns = (t * 1e9).round() as u64;
        let input = FrameIn {
            index,
            source,
            t,
            follower,
            pan,
            image: frame.image,
            stamp_ns,
            bag: None,
        };
        session.frame(input, || Ok(fps))?;
    }
    let (processed, broken) = session.finish(|t| (t * fps).round() as u64)?;
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
        return Err(cmd::Partial(summary).into());
    }
    errln!("track: {summary}");
    Ok(())
}

/// `--fps`, else the stream's own rate, else 30 (said on stderr).
fn frame_rate(args: &Args, frames: &FrameSource) -> Result<f64, CliError> {
    let fps = match (args.fps, frames.frame_rate()) {
        (Some(f), _) => f,
        (None, Some(f)) => f,
        (None, None) => {
            errln!("track: no --fps and no frame rate in the input: assuming 30 frames/s");
            30.0
        }
    };
    Ok(cmd::numbers::check_fps(fps).map_err(|e| format!("the input's frame rate: {e}"))?)
}
