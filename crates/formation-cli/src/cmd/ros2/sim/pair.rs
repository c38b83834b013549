//! `ros2-sim --scenario FILE`: the demo's robot pair, its follower driven by `cmd_vel`.

use std::fmt::Write as _;
use std::path::Path;
use std::time::{Duration, Instant};

use formation_io::frames::GreyImage;
use formation_ros2::msg;
use formation_ros2::topics::{reliable, subscription};
use formation_sim::pair::RobotPair;
use formation_sim::scenario_file::ScenarioSpec;
use unicycle::Inputs;

use super::{Args, CameraOut, epoch_ns};
use crate::cmd::{self, CliError, output::Staged, progress::errln};

/// Runs the pair until the scenario ends (or a signal).
pub fn run(args: &Args, file: &Path) -> Result<(), CliError> {
    let spec = ScenarioSpec::load(file)?;
    let mut pair = RobotPair::new(&spec)?;
    if let Some(path) = &args.write_controller {
        return write_controller(&pair, &spec, path);
    }
    let mut staged = Staged::new();
    if let Some(path) = &args.truth {
        cmd::output::refuse_inputs_as_outputs(&[("--truth", path)], &[("--scenario", file)])?;
        cmd::prepare_out_file(path)?;
    }
    let cam = pair.config().camera;
    let camera = pose::Camera::pinhole(
        pose::Intrinsics::from_hfov(
            cam.hfov_deg.to_radians(),
            cam.width as u32,
            cam.height as u32,
        )
        .map_err(|e| format!("{}: the scenario's camera: {e}", file.display()))?,
        cam.width as u32,
        cam.height as u32,
    );
    let Some(mut out) = CameraOut::open(args)? else {
        return Ok(());
    };
    let commands: ros2_client::dds::Subscription<msg::Twist> =
        subscription(&mut out.node, &args.cmd_vel_topic, &reliable(10))?;
    let base_ns = epoch_ns()?;
    let mut command = Inputs::new(0.0, 0.0);
    let (mut answered, mut bad) = (0usize, 0usize);
    let mut csv = String::from(
        "step,t,l12,alpha12,beta12,l12_desired,alpha12_desired,v2_command,w2_command,command_received,occluded,follower_x,follower_y,follower_theta\n",
    );
    let mut progress =
        cmd::progress::Progress::new("ros2-sim", "steps", Some(pair.steps() as u64 + 1));
    let started = Instant::now();
    loop {
        if cmd::interrupt::requested().is_some() {
            break;
        }
        let t = pair.t();
        let frame = pair.render()?;
        let (width, height) = frame.dimensions();
        let grey = GreyImage {
            width: width as usize,
            height: height as usize,
            data: frame.into_raw(),
        };
        let odometry = pair.odometry();
        let stamp_ns = base_ns + (t * 1e9).round() as u64;
        // At the scenario's frame rate when rendering and the node keep up; later when not
        // (lockstep: the simulated time waits for the follower's answer).
        std::thread::sleep(
            (started + Duration::from_secs_f64(t)).saturating_duration_since(Instant::now()),
        );
        out.publish(args, stamp_ns, &camera, (odometry.v, odometry.w), &grey)?;
        // Lockstep: the follower's answer to this frame, or the last command after the
        // timeout (a frame the node dropped, or a node that does not drive).
        let deadline = Instant::now() + Duration::from_secs_f64(args.step_timeout);
        let mut got = false;
        while !got && Instant::now() < deadline && cmd::interrupt::requested().is_none() {
            while let Ok(Some((m, _))) = commands.take() {
                let c = Inputs::new(m.linear.x, m.angular.z);
                if c.v.is_finite() && c.w.is_finite() {
                    command = c;
                } else {
                    bad += 1;
                    progress.println(&format!(
                        "ros2-sim: step {}: cmd_vel linear.x = {}, angular.z = {}: not finite, ignored",
                        pair.step(),
                        m.linear.x,
                        m.angular.z
                    ));
                }
                got = true;
            }
            if !got {
                std::thread::sleep(Duration::from_micros(200));
            }
        }
        answered += usize::from(got);
        let truth = pair.truth()?;
        let goal = pair.controller_at(t)?;
        let (_, f) = pair.poses();
        writeln!(
            csv,
            "{},{t:.6},{},{},{},{},{},{},{},{},{},{},{},{}",
            pair.step(),
            truth.l12,
            truth.alpha12,
            truth.beta12,
            goal.l12_desired,
            goal.alpha12_desired,
            command.v,
            command.w,
            got,
            pair.occluded(),
            f.x,
            f.y,
            f.theta
        )?;
        progress.inc();
        if pair.step() >= pair.steps() {
            break;
        }
        pair.advance(command)?;
    }
    progress.finish();
    if let Some(path) = &args.truth {
        staged.write(path, csv)?;
        staged.commit()?;
    }
    let steps = pair.step() + 1;
    errln!(
        "ros2-sim: {steps} steps of {} ({:.1} s simulated in {:.1} s), {answered} answered by a command on {}{}",
        file.display(),
        pair.t(),
        started.elapsed().as_secs_f64(),
        args.cmd_vel_topic,
        if bad > 0 {
            format!(", {bad} non-finite commands ignored")
        } else {
            String::new()
        }
    );
    cmd::interrupt::stopped(|| format!("{steps} steps simulated"))
}

/// `--write-controller`: the demo follower's controller as a `--control` file.
fn write_controller(pair: &RobotPair, spec: &ScenarioSpec, path: &Path) -> Result<(), CliError> {
    let goal = pair.controller_at(0.0)?;
    let mut text = format!(
        "# The demo follower's controller for this scenario (ros2-sim --write-controller):\n\
         # hold the starting formation, then the scenario's set-point changes.\nleader: 1\nl12_desired: {:?}\nalpha12_desired: {:?}\nk_l: {:?}\nk_alpha: {:?}\n",
        goal.l12_desired, goal.alpha12_desired, goal.k_l, goal.k_alpha
    );
    if !spec.setpoints.is_empty() {
        text.push_str("setpoints:\n");
        for s in &spec.setpoints {
            write!(text, "  - {{at: {:?}", s.at)?;
            if let Some(l) = s.l12 {
                write!(text, ", l12: {l:?}")?;
            }
            if let Some(a) = s.alpha12 {
                write!(text, ", alpha12: {a:?}")?;
            }
            text.push_str("}\n");
        }
    }
    if let Some(v) = goal.max_v {
        writeln!(text, "max_v: {v:?}")?;
    }
    if let Some(w) = goal.max_w {
        writeln!(text, "max_w: {w:?}")?;
    }
    cmd::prepare_out_file(path)?;
    let mut staged = Staged::new();
    staged.write(path, text)?;
    staged.commit()?;
    errln!("ros2-sim: wrote {}", path.display());
    Ok(())
}
