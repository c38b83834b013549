//! `formation-tracker demo`: the project's showcase, the reference scenario with the
//! synthetic camera in the loop (`formation_sim::demo`).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use clap::Args as ClapArgs;
use formation_sim::demo::{DemoConfig, DemoError, DemoFrame, DemoRun, DemoSummary, run_demo_until};
use formation_sim::plot::{fig12_panels, fig13_panels, shade, write_png, write_svg};
use formation_sim::reproduce::StepRecord;

use super::CliError;
use super::output::Staged;
use super::progress::errln;

/// Figure size, pixels.
const FIGURE_SIZE: (u32, u32) = (1000, 750);

/// Run the end-to-end demo: every frame of the reference scenario rendered on the
/// follower's camera (640x480, noise and blur), detected, posed and tracked, with a 1 s
/// occlusion of the leader in the middle.
///
/// Writes into DIR: summary.json (mean square errors, frames detected, timing, coasting
/// and re-acquisition), series.csv (one row per frame: true / measured / estimated
/// formation variables and velocities, status, markers, timing), fig12.svg/png and
/// fig13.svg/png (Figs. 12-13 from the vision measurements), frames/frame-NNNN.png
/// (annotated frames, one a second), strip.png (those frames side by side) and demo.mcap
/// (robot 2's camera with its markers, reprojected rigs and estimates, for Foxglove);
/// prints a summary.
#[derive(Debug, ClapArgs)]
pub struct Args {
    /// Directory to write the demo's outputs into (created if missing).
    #[arg(long, value_name = "DIR", default_value = "out/demo")]
    out: PathBuf,
    /// The followers steer on their trackers' estimates instead of the truth.
    #[arg(long)]
    closed_loop: bool,
    /// Robots in the chain (2 to 6), each following the one ahead with its own camera and
    /// tracker.
    #[arg(long, value_name = "N", default_value_t = 2, value_parser = super::numbers::chain_robots)]
    robots: usize,
    /// Seed of the sensor noise.
    #[arg(long, value_name = "N", default_value_t = 1)]
    seed: u64,
    /// Also save the first follower's raw camera frames as a test sequence for `track`:
    /// DIR/frames/frame-NNNN.png, DIR/camera.yaml (the camera's calibration) and
    /// DIR/inputs.csv (the follower's inputs per frame). Then: `formation-tracker track
    /// DIR/frames --camera DIR/camera.yaml --inputs DIR/inputs.csv --fps 30`.
    #[arg(long, value_name = "DIR")]
    save_frames: Option<PathBuf>,
    /// Run this scenario file (YAML, or JSON if named .json; the file of `reproduce dukf
    /// --scenario`) instead of the built-in reference scenario: the robots' start, the
    /// leader's inputs, the follower's set-points, frame rate and duration, and in its
    /// optional `vision` section the camera, rendering (noise, blur, motion blur, lighting
    /// gradient) and occlusion (docs/tracking.md). Two robots only.
    /// fixtures/scenarios/far.yaml: the leader 3-4 m away.
    #[arg(long, value_name = "FILE")]
    scenario: Option<PathBuf>,
}

/// Runs `demo`.
pub fn run(args: Args) -> Result<(), CliError> {
    let config = config_of(&args)?;
    refuse_inputs_as_outputs(&args)?;
    super::interrupt::install()?;
    announce_long_render(&config)?;
    super::prepare_out_dir(&args.out)?;
    // Every file goes to a temporary name and is renamed when the whole run is done: an
    // interrupted or failed demo leaves an earlier folder as it was.
    let mut staged = Staged::new();
    let mut saver = args
        .save_frames
        .as_deref()
        .map(|dir| FrameSaver::new(dir, &config))
        .transpose()?;
    let mut mcap = McapSaver::new(&mut staged, &args.out.join("demo.mcap"), &config)?;
    let started = std::time::Instant::now();
    errln!(
        "demo: rendering and tracking {} s at {:.0} frames/s, {} robot(s){}...",
        config.duration,
        1.0 / config.dt,
        config.robots,
        if config.closed_loop {
            ", closed loop"
        } else {
            ""
        }
    );
    let mut progress = super::progress::Progress::new("demo", "frames", None);
    let run = run_demo_until(
        &config,
        |step, steps| {
            progress.set_total(steps as u64 + 1);
            progress.set(step as u64 + 1);
        },
        |frame| {
            if let Some(saver) = &mut saver {
                saver.save(frame);
            }
            mcap.save(frame);
        },
        || super::interrupt::requested().is_some(),
    );
    progress.finish();
    if let Err(DemoError::Stopped { step, steps }) = &run {
        super::interrupt::stopped(|| {
            format!(
                "{step} of {} steps rendered; nothing written, {} left as it was",
                steps + 1,
                args.out.display()
            )
        })?;
    }
    let run = run?;
    let frames_staged = saver.map(FrameSaver::finish).transpose()?;
    mcap.finish()?;
    super::prepare_out_dir(&args.out.join("frames"))?;
    write_outputs(&mut staged, &args.out, &run, config.occlusion, config.dt)?;
    if let Some(frames) = frames_staged {
        frames.commit()?;
    }
    let stale = stale_outputs(&args.out, &staged);
    staged.commit()?;
    for path in stale {
        let _ = std::fs::remove_file(path);
    }
    super::write_stdout(format_args!(
        "{}",
        summary_text(&run.summary, started.elapsed().as_secs_f64())
    ))?;
    errln!("demo: wrote {}", args.out.display());
    Ok(())
}

/// The demo's configuration: the scenario file's, or the built-in reference with `--robots`;
/// `--closed-loop` and `--seed` on top.
fn config_of(args: &Args) -> Result<DemoConfig, CliError> {
    let mut config = match &args.scenario {
        Some(path) => {
            if args.robots != 2 {
                return Err(super::Usage(format!(
                    "--robots {} with --scenario: a scenario file describes two robots (a leader and one follower)",
                    args.robots
                ))
                .into());
            }
            let spec = formation_sim::scenario_file::ScenarioSpec::load(path)?;
            DemoConfig {
                closed_loop: args.closed_loop,
                ..DemoConfig::from_scenario(&spec)
            }
        }
        None => DemoConfig {
            robots: args.robots,
            closed_loop: args.closed_loop,
            ..DemoConfig::default()
        },
    };
    config.render.seed = args.seed;
    Ok(config)
}

/// Refuses, before any work, `--save-frames` inside `--out` and `--out` onto `--scenario`.
fn refuse_inputs_as_outputs(args: &Args) -> Result<(), CliError> {
    if let Some(frames) = &args.save_frames {
        super::output::refuse_inputs_as_outputs(
            &[("--save-frames", frames)],
            &[("--out", &args.out)],
        )?;
    }
    if let Some(scenario) = &args.scenario {
        super::output::refuse_inputs_as_outputs(
            &[("--out", &args.out)],
            &[("--scenario", scenario)],
        )?;
    }
    Ok(())
}

/// Says on stderr how long rendering will take when it is over a minute.
fn announce_long_render(config: &DemoConfig) -> Result<(), CliError> {
    let estimate = formation_sim::demo::estimate_render_seconds(config)?;
    if estimate > 60.0 {
        let subframes = config.motion_blur.map_or(1, |mb| mb.subframes.max(1));
        errln!(
            "demo: rendering will take about {} (estimated from a probe frame: {} frames of {}x{}, supersampling {}, {subframes} sub-frame(s)); lower them in the scenario's vision section to go faster",
            duration_text(estimate),
            ((config.duration / config.dt).round() as usize + 1) * (config.robots - 1),
            config.camera.width,
            config.camera.height,
            config.render.supersampling,
        );
    }
    Ok(())
}

/// `seconds` as `12 min` or `2.5 h`.
fn duration_text(seconds: f64) -> String {
    if seconds < 5400.0 {
        format!("{:.0} min", seconds / 60.0)
    } else {
        format!("{:.1} h", seconds / 3600.0)
    }
}

/// The demo's own outputs in `out` that this run does not write (the figures of a follower
/// an earlier run with more robots had, strip frames of other steps): removed once the new
/// files are in place, so that the folder is one run's.
fn stale_outputs(out: &Path, staged: &Staged) -> Vec<PathBuf> {
    let mut stale = Vec::new();
    let is_demo_file = |dir_is_frames: bool, name: &str| {
        if dir_is_frames {
            name.starts_with("frame-") && name.ends_with(".png")
        } else {
            (name.starts_with("fig12-robot") || name.starts_with("fig13-robot"))
                && (name.ends_with(".png") || name.ends_with(".svg"))
        }
    };
    for (dir, frames) in [(out.to_path_buf(), false), (out.join("frames"), true)] {
        let Ok(entries) = std::fs::read_dir(&dir) else {
            continue;
        };
        for entry in entries.flatten() {
            let name = entry.file_name().to_string_lossy().into_owned();
            let path = entry.path();
            if is_demo_file(frames, &name) && !staged.contains(&path) {
                stale.push(path);
            }
        }
    }
    stale
}

fn write_outputs(
    staged: &mut Staged,
    out: &Path,
    run: &DemoRun,
    occlusion: Option<(f64, f64)>,
    dt: f64,
) -> Result<(), CliError> {
    let json = serde_json::to_string_pretty(&run.summary)? + "\n";
    staged.write(&out.join("summary.json"), json)?;
    staged.write(&out.join("series.csv"), series_csv(run))?;
    // Figs. 12-13 for every pair: robot 2's as fig12/fig13, robot k's as figNN-robotK.
    for (i, trace) in run.traces.iter().enumerate() {
        let records: Vec<StepRecord> = trace.records.iter().map(|r| r.step.clone()).collect();
        let suffix = if i == 0 {
            String::new()
        } else {
            format!("-robot{}", trace.follower)
        };
        let mut fig12 = fig12_panels(&records);
        shade(&mut fig12, occlusion);
        let mut path = |name: String| staged.path(&out.join(name));
        write_svg(&path(format!("fig12{suffix}.svg")), &fig12, FIGURE_SIZE)?;
        write_png(&path(format!("fig12{suffix}.png")), &fig12, FIGURE_SIZE)?;
        let mut fig13 = fig13_panels(&records);
        shade(&mut fig13, occlusion);
        write_svg(&path(format!("fig13{suffix}.svg")), &fig13, FIGURE_SIZE)?;
        write_png(&path(format!("fig13{suffix}.png")), &fig13, FIGURE_SIZE)?;
    }
    for frame in &run.strip {
        let path = out
            .join("frames")
            .join(format!("frame-{:04}.png", frame.step));
        frame
            .image
            .save_with_format(staged.path(&path), image::ImageFormat::Png)
            .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
    }
    if let Some(strip) = contact_sheet(run, dt)? {
        let path = out.join("strip.png");
        strip
            .save_with_format(staged.path(&path), image::ImageFormat::Png)
            .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
    }
    Ok(())
}

/// The strip's frames at half size, three to a row, each captioned with its time and what the
/// frame gave: the markers read and the leader's track (or that the leader was hidden).
fn contact_sheet(run: &DemoRun, dt: f64) -> Result<Option<image::RgbImage>, CliError> {
    let records = run.traces.first().map_or(&[][..], |t| &t.records[..]);
    let frames: Vec<(image::RgbImage, String)> = run
        .strip
        .iter()
        .map(|f| (f.image.clone(), strip_caption(f, dt, records)))
        .collect();
    Ok(formation_sim::annotate::contact_sheet(&frames, 3, 0.5)?)
}

/// Two lines: `t = 2.00 s   read 1/3, 1/4` (or `leader hidden`) and `tracking   l12 1.031 m`,
/// from the frame and the record of its step (the first frame has none: it only starts the
/// track).
fn strip_caption(
    frame: &formation_sim::demo::StripFrame,
    dt: f64,
    records: &[formation_sim::demo::DemoRecord],
) -> String {
    let t = frame.step as f64 * dt;
    let record = records.iter().find(|r| (r.step.t - t).abs() < dt / 2.0);
    let seen = if record.is_some_and(|r| r.occluded) {
        "leader hidden".to_owned()
    } else if frame.labels.is_empty() {
        "no marker read".to_owned()
    } else {
        format!("read {}", frame.labels.join(", "))
    };
    let track = match record.map(|r| (r.status, r.step.estimated[0])) {
        Some((Some(s), l12)) => format!("{}   l12 {l12:.3} m", format!("{s:?}").to_lowercase()),
        Some((None, _)) => "no track".to_owned(),
        None => "first frame: the track starts".to_owned(),
    };
    format!("t = {t:.2} s   {seen}\n{track}")
}

fn series_csv(run: &DemoRun) -> String {
    let mut s = String::from(
        "follower,leader,t,l12_true,alpha12_true,beta12_true,l12_measured,alpha12_measured,\
         beta12_measured,l12_estimated,alpha12_estimated,beta12_estimated,l12_std,alpha12_std,\
         beta12_std,v1_true,w1_true,v1_estimated,w1_estimated,v1_std,w1_std,status,measurement,\
         occluded,markers,leaders,detect_ms,pose_ms,track_ms,nis\n",
    );
    for tr in &run.traces {
        for r in &tr.records {
            let st = &r.step;
            let status = r
                .status
                .map_or("none".to_owned(), |x| format!("{x:?}").to_lowercase());
            let used = r
                .measurement
                .map_or("none".to_owned(), |x| format!("{x:?}").to_lowercase());
            let _ = writeln!(
                s,
                "{},{},{:.6},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{status},{used},{},{},{},{:.4},{:.4},{:.4},{}",
                tr.follower,
                tr.leader,
                st.t,
                st.truth[0],
                st.truth[1],
                st.truth[2],
                st.measured[0],
                st.measured[1],
                st.measured[2],
                st.estimated[0],
                st.estimated[1],
                st.estimated[2],
                st.estimated_std[0],
                st.estimated_std[1],
                st.estimated_std[2],
                st.v1_true,
                st.w1_true,
                st.v1_estimated,
                st.w1_estimated,
                st.v1_std,
                st.w1_std,
                r.occluded,
                r.markers,
                r.leaders,
                r.timing.detect_ms,
                r.timing.pose_ms,
                r.timing.track_ms,
                r.nis.map_or(String::new(), |x| format!("{x:.4}")),
            );
        }
    }
    s
}

/// The readable summary printed at the end.
fn summary_text(s: &DemoSummary, wall_s: f64) -> String {
    let mut t = String::new();
    let _ = writeln!(
        t,
        "demo: robot 2 tracking robot 1 through its camera ({} robots, {})",
        s.robots,
        if s.closed_loop {
            "closed loop"
        } else {
            "open loop"
        }
    );
    let _ = writeln!(t, "  quantity   vision MSE   tracked MSE   paper");
    let _ = writeln!(
        t,
        "  l12        {:10.3e}   {:11.3e}   1.88e-4",
        s.mse.meas_l12, s.mse.l12
    );
    let _ = writeln!(
        t,
        "  alpha12    {:10.3e}   {:11.3e}   7.22e-5",
        s.mse.meas_alpha12, s.mse.alpha12
    );
    let _ = writeln!(
        t,
        "  beta12     {:10.3e}   {:11.3e}",
        s.mse.meas_beta12, s.mse.beta12
    );
    let _ = writeln!(t, "  v1                      {:11.3e}", s.mse.v1);
    let _ = writeln!(t, "  w1                      {:11.3e}", s.mse.w1);
    let _ = writeln!(
        t,
        "  tracked MSE over the {} frames with a measurement: l12 {:.3e}, alpha12 {:.3e}, beta12 {:.3e}; over the {} coasting frames: l12 {:.3e}, alpha12 {:.3e}, beta12 {:.3e}",
        s.frames_detected,
        s.mse_detected[0],
        s.mse_detected[1],
        s.mse_detected[2],
        s.frames_coasting,
        s.mse_coasting[0],
        s.mse_coasting[1],
        s.mse_coasting[2]
    );
    let _ = writeln!(
        t,
        "  velocity RMS after 2 s: v1 {:.4} m/s, w1 {:.4} rad/s",
        s.rms_velocity_after_2s[0], s.rms_velocity_after_2s[1]
    );
    let _ = writeln!(
        t,
        "  NIS over {} updates: mean {:.2} (95 % bounds {:.2} to {:.2}), {:.0} % of frames inside the per-frame 95 % interval",
        s.nis.frames,
        s.nis.mean,
        s.nis.mean_bounds_95[0],
        s.nis.mean_bounds_95[1],
        100.0 * s.nis.inside_95
    );
    let _ = writeln!(
        t,
        "  frames {} (t = 0 initialises the tracker; of the {} scored, leader detected in {}, hidden in {}), coasting {}, max coasting l12 error {:.3} m",
        s.frames,
        s.frames_scored,
        s.frames_detected,
        s.frames_occluded,
        s.frames_coasting,
        s.max_coasting_error_l12
    );
    let _ = writeln!(
        t,
        "  after the occlusion: {} {}",
        if s.reacquired_same_id {
            "re-acquired as robot 1 by the same track"
        } else {
            "NOT re-acquired by the same track"
        },
        s.reacquired_after_s
            .map_or(String::new(), |x| format!("after {x:.3} s"))
    );
    for p in s.pairs.iter().skip(1) {
        let _ = writeln!(
            t,
            "  robot {} tracking robot {}: tracked MSE l12 {:.3e} (vision {:.3e}), alpha12 {:.3e} (vision {:.3e}), beta12 {:.3e}; leader detected in {} of {} scored frames, coasting {}",
            p.follower,
            p.leader,
            p.mse[0],
            p.mse_meas[0],
            p.mse[1],
            p.mse_meas[1],
            p.mse[2],
            p.frames_detected,
            p.frames_scored,
            p.frames_coasting
        );
    }
    let _ = writeln!(
        t,
        "  formation: true l12 within {:.1} % of its set-point after 3 s",
        100.0 * s.max_formation_error_after_3s
    );
    let _ = writeln!(
        t,
        "  speed: detect {:.2} ms, whole pipeline {:.2} ms per frame (median), {:.0} frames/s; rendering {:.1} s; total {:.1} s",
        s.detect_ms_median, s.pipeline_ms_median, s.frames_per_second, s.render_s, wall_s
    );
    t
}

/// Writes the first follower's frames, its inputs and the camera's calibration
/// (`demo --save-frames`). The first write error is kept and reported at the end.
struct FrameSaver {
    dir: PathBuf,
    csv: String,
    error: Option<String>,
    /// Its files, committed with the demo's.
    staged: Staged,
}

impl FrameSaver {
    fn new(dir: &Path, config: &DemoConfig) -> Result<Self, CliError> {
        super::prepare_out_dir(&dir.join("frames"))?;
        let camera = config.camera;
        let k = pose::Intrinsics::from_hfov(
            camera.hfov_deg.to_radians(),
            camera.width as u32,
            camera.height as u32,
        )?
        .matrix();
        let row = |r: usize| format!("{:?}, {:?}, {:?}", k[(r, 0)], k[(r, 1)], k[(r, 2)]);
        let yaml = format!(
            "%YAML:1.0\n---\n# The demo camera: {w}x{h}, {hfov} degrees horizontal field of view, no distortion.\nimage_width: {w}\nimage_height: {h}\ncamera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ {}, {}, {} ]\ndistortion_coefficients: !!opencv-matrix\n   rows: 1\n   cols: 5\n   dt: d\n   data: [ 0., 0., 0., 0., 0. ]\n",
            row(0),
            row(1),
            row(2),
            w = camera.width,
            h = camera.height,
            hfov = camera.hfov_deg,
        );
        let mut staged = Staged::new();
        staged.write(&dir.join("camera.yaml"), yaml)?;
        Ok(Self {
            dir: dir.to_path_buf(),
            csv: "frame,v2,w2\n".into(),
            error: None,
            staged,
        })
    }

    fn save(&mut self, frame: &DemoFrame<'_>) {
        if frame.robot != 2 || self.error.is_some() {
            return;
        }
        let path = self
            .dir
            .join("frames")
            .join(format!("frame-{:04}.png", frame.step));
        if let Err(e) = frame
            .image
            .save_with_format(self.staged.path(&path), image::ImageFormat::Png)
        {
            self.error = Some(format!("cannot write {}: {e}", path.display()));
            return;
        }
        let _ = writeln!(
            self.csv,
            "{},{:?},{:?}",
            frame.step, frame.inputs.v, frame.inputs.w
        );
    }

    /// Its files, complete and still under their temporary names.
    fn finish(mut self) -> Result<Staged, CliError> {
        if let Some(e) = self.error {
            return Err(e.into());
        }
        self.staged.write(&self.dir.join("inputs.csv"), &self.csv)?;
        errln!(
            "demo: saved the raw frames of robot 2's camera to {}",
            self.dir.display()
        );
        Ok(self.staged)
    }
}

/// Writes robot 2's camera, tracked as `track` would track its saved frames, to
/// `demo.mcap` (`docs/bags.md`): the frames, marker outlines and reprojected rigs, camera to
/// leader transforms and the estimates. The first error is kept and reported at the end.
struct McapSaver {
    path: PathBuf,
    dt: f64,
    mount: formation_tracker::mount::CameraMount,
    pipeline: formation_tracker::pipeline::Pipeline,
    writer: Option<formation_io::foxglove::FoxgloveWriter<std::io::BufWriter<std::fs::File>>>,
    error: Option<String>,
}

impl McapSaver {
    fn new(staged: &mut Staged, path: &Path, config: &DemoConfig) -> Result<Self, CliError> {
        use fiducial::{Detector, DetectorConfig, Dictionary};
        use formation_tracker::tracker::{Tracker, TrackerConfig};
        let (dt, mount) = (config.dt, config.mount);
        let camera = config.camera;
        let (w, h) = (camera.width as u32, camera.height as u32);
        let intrinsics = pose::Intrinsics::from_hfov(camera.hfov_deg.to_radians(), w, h)?;
        let calibration = pose::Camera::pinhole(intrinsics, w, h);
        let rig = formation_tracker::rig::RigModel::reference();
        let tracker = Tracker::new(TrackerConfig::reference(mount.offset, dt))?;
        let pipeline = formation_tracker::pipeline::Pipeline::new(
            Detector::with_dictionary(DetectorConfig::for_pose(), Dictionary::paper().clone()),
            pose::PoseSolver::new(intrinsics),
            (w, h),
            rig.clone(),
            formation_tracker::robots::RobotConfig::default(),
            tracker,
        );
        let file = staged.create(path)?;
        let writer = formation_io::foxglove::FoxgloveWriter::new(file, rig, calibration, true)
            .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
        Ok(Self {
            path: path.to_path_buf(),
            dt,
            mount,
            pipeline,
            writer: Some(writer),
            error: None,
        })
    }

    fn save(&mut self, frame: &DemoFrame<'_>) {
        if frame.robot != 2 || self.error.is_some() {
            return;
        }
        let Some(writer) = self.writer.as_mut() else {
            return;
        };
        let t = frame.step as f64 * self.dt;
        let (w, h) = (frame.image.width() as usize, frame.image.height() as usize);
        let done =
            match self
                .pipeline
                .process(frame.image.as_raw(), w, h, t, frame.inputs, self.mount)
            {
                Ok(done) => done,
                Err(e) => {
                    self.error = Some(format!("demo.mcap: frame {}: {e}", frame.step));
                    return;
                }
            };
        let out = formation_io::foxglove::FrameOut {
            frame: frame.step as u64,
            stamp_ns: (t * 1e9).round() as u64,
            t,
            image: Some((frame.image.as_raw(), w, h)),
            result: &done,
            markers: self.pipeline.markers(),
        };
        if let Err(e) = writer.frame(&out) {
            self.error = Some(format!("cannot write {}: {e}", self.path.display()));
        }
    }

    fn finish(mut self) -> Result<(), CliError> {
        if let Some(e) = self.error {
            return Err(e.into());
        }
        if let Some(w) = self.writer.take() {
            w.finish()
                .map_err(|e| format!("cannot write {}: {e}", self.path.display()))?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn strip_captions_say_time_markers_and_track() {
        let frame = formation_sim::demo::StripFrame {
            step: 0,
            image: image::RgbImage::new(1, 1),
            labels: vec!["1/3".into(), "1/4".into()],
        };
        assert_eq!(
            strip_caption(&frame, 1.0 / 30.0, &[]),
            "t = 0.00 s   read 1/3, 1/4\nfirst frame: the track starts"
        );
        let no_markers = formation_sim::demo::StripFrame {
            step: 60,
            labels: Vec::new(),
            ..frame
        };
        assert_eq!(
            strip_caption(&no_markers, 1.0 / 30.0, &[]),
            "t = 2.00 s   no marker read\nfirst frame: the track starts"
        );
    }
}
