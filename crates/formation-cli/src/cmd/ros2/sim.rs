//! `formation-tracker ros2-sim`: a camera and the follower's odometry on ROS 2, from a
//! recording (`demo --save-frames` or `track`'s folder layout) at its frame rate.

use std::path::PathBuf;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use clap::Args as ClapArgs;
use formation_io::frames::FrameSource;
use formation_io::inputs::FollowerInputs;
use formation_ros2::topics::{publisher, reliable, sensor_data};
use formation_ros2::{RosEnv, convert, msg};
use ros2_client::dds::Publisher;

use crate::cmd::{self, CliError, progress::errln};

/// Publish a recording as a camera driver and odometry would: DIR/frames (images, sorted by
/// name) as sensor_msgs/msg/Image (mono8), DIR/camera.yaml as sensor_msgs/msg/CameraInfo
/// with every frame, and DIR/inputs.csv (the follower's v2, w2 per frame) as
/// nav_msgs/msg/Odometry stamped like the frame, at --fps (docs/ros2.md).
///
/// `demo --save-frames DIR` writes this layout. Waits for a subscriber to the image topic
/// before the first frame. The DDS domain is ROS_DOMAIN_ID;
/// ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST keeps every packet on the machine.
#[derive(Debug, ClapArgs)]
pub struct Args {
    /// The recording: DIR/frames, DIR/camera.yaml and DIR/inputs.csv.
    #[arg(long, value_name = "DIR")]
    pub replay: PathBuf,
    /// Frames per second, 0.001 to 10000.
    #[arg(long, value_name = "F", default_value_t = 30.0, value_parser = crate::cmd::numbers::fps)]
    pub fps: f64,
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
    /// Publish the recording this many times in a row (stamps keep increasing); 0 repeats
    /// until interrupted (soak tests).
    #[arg(long, value_name = "N", default_value_t = 1)]
    pub repeat: u64,
    /// Seconds to wait for a subscriber to the image topic before giving up.
    #[arg(long, value_name = "S", default_value_t = 20.0, value_parser = crate::cmd::numbers::positive)]
    pub wait: f64,
}

/// Runs the publisher.
pub fn run(args: Args) -> Result<(), CliError> {
    cmd::interrupt::install()?;
    let env = RosEnv::from_env()?;
    let camera = cmd::load_calibration(&args.replay.join("camera.yaml"))?;
    let inputs = FollowerInputs::from_path(&args.replay.join("inputs.csv"))?;
    let folder = args.replay.join("frames");
    let mut frames = FrameSource::open(&folder)?;
    let mut node = env.node(&args.namespace, "formation_sim")?;
    // Reliable writers with a deep queue: a reliable writer still serves best-effort
    // readers (the node's sensor-data QoS), and a reliable reader gets every frame.
    let q = reliable(8);
    let images: Publisher<msg::Image> = publisher(&mut node, &args.image_topic, &q)?;
    let infos: Publisher<msg::CameraInfo> = publisher(&mut node, &args.camera_info_topic, &q)?;
    let odom: Publisher<msg::Odometry> = publisher(&mut node, &args.odom_topic, &sensor_data(8))?;
    let deadline = Instant::now() + Duration::from_secs_f64(args.wait);
    while images.get_subscription_count(&node) == 0 || infos.get_subscription_count(&node) == 0 {
        if Instant::now() > deadline {
            return Err(format!(
                "ros2-sim: no subscriber to {} and {} within {} s",
                args.image_topic, args.camera_info_topic, args.wait
            )
            .into());
        }
        if cmd::interrupt::requested().is_some() {
            return Ok(());
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    // Matched writers may still be unknown to the reader's side for a moment.
    std::thread::sleep(Duration::from_millis(500));
    let epoch = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_err(|e| format!("the clock is before 1970: {e}"))?;
    let base_ns = epoch.as_secs() * 1_000_000_000;
    let start = Instant::now();
    let mut sent = 0u64;
    let mut pass = 0u64;
    let mut offset = 0u64;
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
        let index = frame.index;
        let k = offset + index;
        let t = k as f64 / args.fps;
        let stamp_ns = base_ns + (t * 1e9).round() as u64;
        let header = msg::Header {
            stamp: msg::Time::from_ns(stamp_ns),
            frame_id: args.frame_id.clone(),
        };
        let (v, w) = inputs
            .at(k, t)
            .map_or((0.0, 0.0), |s| (s.inputs.v, s.inputs.w));
        let wait = (start + Duration::from_secs_f64(t)).saturating_duration_since(Instant::now());
        std::thread::sleep(wait);
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
        odom.publish(o).map_err(|e| fail("odometry", &e))?;
        infos
            .publish(convert::camera_info(&camera, header.clone()))
            .map_err(|e| fail("camera_info", &e))?;
        let img = frame.image;
        images
            .publish(msg::Image {
                header,
                height: img.height as u32,
                width: img.width as u32,
                encoding: "mono8".into(),
                is_bigendian: 0,
                step: img.width as u32,
                data: msg::Bytes(img.data.clone()),
            })
            .map_err(|e| fail("image", &e))?;
        sent += 1;
    }
    // Let the last frames leave before the participant goes away.
    std::thread::sleep(Duration::from_millis(300));
    errln!("ros2-sim: published {sent} frames at {} frames/s", args.fps);
    Ok(())
}
