//! `formation-tracker ros2-sim`: a camera and the follower's odometry on ROS 2, from a
//! recording (`demo --save-frames` or `track`'s folder layout) at its frame rate, or from
//! the demo's simulated robot pair, whose follower moves by the `cmd_vel` it receives.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use clap::Args as ClapArgs;
use formation_io::frames::{FrameSource, GreyImage};
use formation_io::inputs::FollowerInputs;
use formation_ros2::topics::{publisher, reliable, sensor_data};
use formation_ros2::{RosEnv, convert, msg};
use ros2_client::dds::{Node, Publisher};

use crate::cmd::{self, CliError, progress::errln};

mod pair;

/// Publish a camera and the follower's odometry on ROS 2, from a recording or from a
/// simulated robot pair (docs/ros2.md).
///
/// --replay DIR: DIR/frames (images, sorted by name) as sensor_msgs/msg/Image (mono8),
/// DIR/camera.yaml as sensor_msgs/msg/CameraInfo with every frame, and DIR/inputs.csv (the
/// follower's v2, w2 per frame) as nav_msgs/msg/Odometry stamped like the frame, at --fps.
/// `demo --save-frames DIR` writes this layout.
///
/// --scenario FILE: the demo's robot pair of a scenario file. Each step renders the
/// follower's camera and publishes it with its CameraInfo and the follower's odometry, then
/// waits up to --step-timeout for a geometry_msgs/msg/Twist on --cmd-vel-topic and moves the
/// follower by the latest one through the scenario's actuation. Frames go out at the
/// scenario's frame rate when rendering and the node keep up, later when not; stamps step by
/// the frame period either way. --truth writes the true formation per step.
///
/// Waits for a subscriber to the images and the calibration before the first frame. The DDS
/// domain is ROS_DOMAIN_ID; ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST keeps every packet on
/// the machine.
#[derive(Debug, ClapArgs)]
#[command(group(clap::ArgGroup::new("source").required(true).args(["replay", "scenario"])))]
pub struct Args {
    /// The recording: DIR/frames, DIR/camera.yaml and DIR/inputs.csv.
    #[arg(long, value_name = "DIR")]
    pub replay: Option<PathBuf>,
    /// A scenario file (YAML, or JSON if named .json; as for `demo --scenario`): simulate
    /// its robot pair.
    #[arg(long, value_name = "FILE", conflicts_with = "replay")]
    pub scenario: Option<PathBuf>,
    /// --replay: frames per second, 0.001 to 10000 (--scenario: the scenario's rate).
    #[arg(long, value_name = "F", default_value_t = 30.0, value_parser = crate::cmd::numbers::fps)]
    pub fps: f64,
    /// --replay: publish the recording this many times in a row (stamps keep increasing);
    /// 0 repeats until interrupted (soak tests).
    #[arg(long, value_name = "N", default_value_t = 1)]
    pub repeat: u64,
    /// --scenario: the follower's commands (geometry_msgs/msg/Twist).
    #[arg(long, value_name = "TOPIC", default_value = "cmd_vel")]
    pub cmd_vel_topic: String,
    /// --scenario: seconds to wait each step for a command before moving on with the latest
    /// one (standing still before any).
    #[arg(long, value_name = "S", default_value_t = 1.0, value_parser = crate::cmd::numbers::positive)]
    pub step_timeout: f64,
    /// --scenario: write the true formation, the demo's set-points and the follower's
    /// commands per step to this CSV (docs/ros2.md).
    #[arg(long, value_name = "CSV")]
    pub truth: Option<PathBuf>,
    /// --scenario: write the controller file of the demo's follower (holding the starting
    /// formation, then the scenario's set-point changes) for `ros2 --control`, and exit.
    #[arg(long, value_name = "FILE", requires = "scenario")]
    pub write_controller: Option<PathBuf>,
    /// The namespace topic names are resolved in.
    #[arg(long, value_name = "NS", default_value = "/")]
    pub namespace: String,
    /// Image topic.
    #[arg(long, value_name = "TOPIC", default_value = "image_raw")]
    pub image_topic: String,
    /// CameraInfo topic.
    #[arg(long, value_name = "TOPIC", default_value = "camera_info")]
    pub camera_info_topic: String,
    /// Odometry topic.
    #[arg(long, value_name = "TOPIC", default_value = "odom")]
    pub odom_topic: String,
    /// The images' optical frame.
    #[arg(long, value_name = "FRAME", default_value = "camera")]
    pub frame_id: String,
    /// Seconds to wait for a subscriber to the image topic before giving up.
    #[arg(long, value_name = "S", default_value_t = 20.0, value_parser = crate::cmd::numbers::positive)]
    pub wait: f64,
}

/// Runs the publisher.
pub fn run(args: Args) -> Result<(), CliError> {
    cmd::interrupt::install()?;
    match (&args.replay, &args.scenario) {
        (Some(dir), _) => replay(&args, dir),
        (None, Some(file)) => pair::run(&args, file),
        (None, None) => Err(cmd::Usage("give --replay DIR or --scenario FILE".into()).into()),
    }
}

/// The publishers of a camera and its robot's odometry.
struct CameraOut {
    node: Node,
    images: Publisher<msg::Image>,
    infos: Publisher<msg::CameraInfo>,
    odom: Publisher<msg::Odometry>,
}

impl CameraOut {
    /// Joins the domain and waits (up to --wait) for a subscriber to the images and the
    /// calibration; `None` if interrupted meanwhile.
    fn open(args: &Args) -> Result<Option<Self>, CliError> {
        let env = RosEnv::from_env()?;
        let mut node = env.node(&args.namespace, "formation_sim")?;
        // Reliable writers with a deep queue: a reliable writer still serves best-effort
        // readers (the node's sensor-data QoS), and a reliable reader gets every frame.
        let q = reliable(8);
        let images = publisher(&mut node, &args.image_topic, &q)?;
        let infos = publisher(&mut node, &args.camera_info_topic, &q)?;
        let odom = publisher(&mut node, &args.odom_topic, &sensor_data(8))?;
        let deadline = Instant::now() + Duration::from_secs_f64(args.wait);
        while images.get_subscription_count(&node) == 0 || infos.get_subscription_count(&node) == 0
        {
            if Instant::now() > deadline {
                return Err(format!(
                    "ros2-sim: no subscriber to {} and {} within {} s",
                    args.image_topic, args.camera_info_topic, args.wait
                )
                .into());
            }
            if cmd::interrupt::requested().is_some() {
                return Ok(None);
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        // Matched writers may still be unknown to the reader's side for a moment.
        std::thread::sleep(Duration::from_millis(500));
        Ok(Some(Self {
            node,
            images,
            infos,
            odom,
        }))
    }

    /// Publishes one frame: the odometry `(v, w)`, the calibration and the image, all
    /// stamped `stamp_ns`.
    fn publish(
        &self,
        args: &Args,
        stamp_ns: u64,
        camera: &pose::Camera,
        (v, w): (f64, f64),
        image: &GreyImage,
    ) -> Result<(), CliError> {
        let header = msg::Header {
            stamp: msg::Time::from_ns(stamp_ns),
            frame_id: args.frame_id.clone(),
        };
        let mut o = msg::Odometry {
            header: msg::Header {
                stamp: header.stamp,
                frame_id: "odom".into(),
            },
            child_frame_id: "base_link".into(),
            ..msg::Odometry::default()
        };
        o.twist.twist.linear.x = v;
        o.twist.twist.angular.z = w;
        let fail =
            |what: &str, e: &dyn std::fmt::Debug| format!("ros2-sim: cannot publish {what}: {e:?}");
        self.odom.publish(o).map_err(|e| fail("odometry", &e))?;
        self.infos
            .publish(convert::camera_info(camera, header.clone()))
            .map_err(|e| fail("camera_info", &e))?;
        self.images
            .publish(msg::Image {
                header,
                height: image.height as u32,
                width: image.width as u32,
                encoding: "mono8".into(),
                is_bigendian: 0,
                step: image.width as u32,
                data: msg::Bytes(image.data.clone()),
            })
            .map_err(|e| fail("image", &e))?;
        Ok(())
    }
}

/// Whole seconds of the wall clock now, in nanoseconds: the first frame's stamp.
fn epoch_ns() -> Result<u64, CliError> {
    let epoch = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_err(|e| format!("the clock is before 1970: {e}"))?;
    Ok(epoch.as_secs() * 1_000_000_000)
}

/// `--replay DIR`.
fn replay(args: &Args, dir: &Path) -> Result<(), CliError> {
    let camera = cmd::load_calibration(&dir.join("camera.yaml"))?;
    let inputs = FollowerInputs::from_path(&dir.join("inputs.csv"))?;
    let folder = dir.join("frames");
    let mut frames = FrameSource::open(&folder)?;
    let Some(out) = CameraOut::open(args)? else {
        return Ok(());
    };
    let base_ns = epoch_ns()?;
    let start = Instant::now();
    let (mut sent, mut pass, mut offset) = (0u64, 0u64, 0u64);
    while cmd::interrupt::requested().is_none() {
        let frame = match frames.next_frame()? {
            Some(f) => f,
            None => {
                pass += 1;
                if (args.repeat != 0 && pass >= args.repeat) || sent == 0 {
                    break;
                }
                offset = sent;
                frames = FrameSource::open(&folder)?;
                continue;
            }
        };
        // Frame `index` of the recording, sent as frame `k` of the stream.
        let index = frame.index;
        let k = offset + index;
        let t = k as f64 / args.fps;
        let stamp_ns = base_ns + (t * 1e9).round() as u64;
        let (v, w) = inputs
            .at(index, index as f64 / args.fps)
            .map_or((0.0, 0.0), |s| (s.inputs.v, s.inputs.w));
        let wait = (start + Duration::from_secs_f64(t)).saturating_duration_since(Instant::now());
        std::thread::sleep(wait);
        out.publish(args, stamp_ns, &camera, (v, w), frame.image)?;
        sent += 1;
    }
    // Let the last frames leave before the participant goes away.
    std::thread::sleep(Duration::from_millis(300));
    errln!("ros2-sim: published {sent} frames at {} frames/s", args.fps);
    Ok(())
}
