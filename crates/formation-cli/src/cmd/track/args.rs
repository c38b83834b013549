//! `track`'s command line.

use std::path::PathBuf;

use clap::Args as ClapArgs;
use formation_tracker::guided::GuidedConfig;
use formation_tracker::mount::CameraMount;

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
    pub input: PathBuf,
    /// Camera calibration (OpenCV YAML or ROS camera_info); for a bag, default: its
    /// CameraInfo.
    #[arg(long, value_name = "FILE")]
    pub camera: Option<PathBuf>,
    /// Bag input: the image topic (sensor_msgs/msg/Image or CompressedImage); default: the
    /// bag's only image topic.
    #[arg(long, value_name = "TOPIC")]
    pub image_topic: Option<String>,
    /// Bag input: the follower's inputs topic (nav_msgs/msg/Odometry, geometry_msgs/msg/Twist
    /// or TwistStamped); default: the bag's only one (Odometry first). --inputs CSV wins.
    #[arg(long, value_name = "TOPIC")]
    pub inputs_topic: Option<String>,
    /// Follower inputs per frame: CSV with `frame` or `t`, `v2`, `w2`, optional `pan`.
    #[arg(long, value_name = "CSV")]
    pub inputs: Option<PathBuf>,
    /// Frame rate, 0.001 to 10000 frames/s; default: the y4m header's, else 30.
    #[arg(long, value_name = "F", value_parser = crate::cmd::numbers::fps)]
    pub fps: Option<f64>,
    /// What every live or recorded run shares: outputs, rig, mount and tracking options.
    #[command(flatten)]
    pub run: RunArgs,
}

/// The options `track` and the ROS 2 node share: outputs, rig, controller, mount and
/// tracking.
#[derive(Debug, Clone, ClapArgs)]
pub struct RunArgs {
    /// Also write the results as MCAP for Foxglove: images, marker and rig annotations,
    /// camera-to-leader transforms and the formation estimate (docs/outputs.md).
    #[arg(long, value_name = "OUT.mcap")]
    pub mcap: Option<PathBuf>,
    /// With --mcap: leave the images out (annotations, transforms and estimates only).
    #[arg(long, requires = "mcap")]
    pub no_images: bool,
    /// Rig file (YAML/JSON); default: the reference rig.
    #[arg(long, value_name = "FILE")]
    pub rig: Option<PathBuf>,
    /// The follower's own separation-bearing controller towards one leader (YAML/JSON:
    /// `leader`, `l12_desired`, `alpha12_desired`, `k_l`, `k_alpha`, optional `max_v`,
    /// `max_w`; docs/tracking.md). The tracker is told it, as a follower knows its own
    /// controller: that leader's IMM filters with its controlled model set. Default: not
    /// told.
    #[arg(long, value_name = "FILE")]
    pub controller: Option<PathBuf>,
    /// One JSON object per frame instead of a text line.
    #[arg(long)]
    pub json: bool,
    /// Camera offset ahead of the follower's axle, metres (the paper's d), 0 to 100.
    #[arg(long, value_name = "M", default_value_t = CameraMount::default().offset,
          value_parser = crate::cmd::numbers::offset, allow_hyphen_values = true)]
    pub mount_offset: f64,
    /// Camera height above the ground, metres, above 0 and below 100.
    #[arg(long, value_name = "M", default_value_t = CameraMount::default().height,
          value_parser = crate::cmd::numbers::height, allow_hyphen_values = true)]
    pub mount_height: f64,
    /// Camera tilt below the horizontal, radians, between -pi/2 and pi/2.
    #[arg(long, value_name = "RAD", default_value_t = 0.0,
          value_parser = crate::cmd::numbers::tilt, allow_hyphen_values = true)]
    pub mount_tilt: f64,
    /// Camera pan (left positive), radians, between -pi and pi, when the inputs CSV has no
    /// `pan` column.
    #[arg(long, value_name = "RAD", default_value_t = 0.0,
          value_parser = crate::cmd::numbers::angle, allow_hyphen_values = true)]
    pub pan: f64,
    /// Accept frames whose size differs from the calibration's by scaling the intrinsics
    /// (frames resized from the calibrated camera's, same aspect ratio). Without it such
    /// frames are errors: their poses would be wrong by the scale.
    #[arg(long = "scale-calibration")]
    pub scale_calibration: bool,
    /// Largest image side accepted, pixels; larger frames are refused from their header,
    /// before they are decoded.
    #[arg(long, value_name = "PX", default_value_t = formation_io::frames::MAX_SIDE,
          value_parser = crate::cmd::numbers::max_side)]
    pub max_side: usize,
    /// The follower's odometry noise `V,W`: white-noise standard deviations of the inputs
    /// it reports (`--inputs` or the bag's odometry), m/s and rad/s, e.g. 0.01,0.01. The
    /// tracker widens each prediction by what that noise moves the formation
    /// (docs/tracking.md); without it the odometry is taken as exact, and with a precise
    /// camera good measurements are then gated. Default: 0,0.
    #[arg(long, value_name = "V,W", value_parser = crate::cmd::numbers::odometry_noise,
          allow_hyphen_values = true)]
    pub odometry_noise: Option<[f64; 2]>,
    /// Seconds without a measurement before a track is dropped.
    #[arg(long, value_name = "S", default_value_t = 2.0, value_parser = crate::cmd::numbers::positive)]
    pub lost_after: f64,
    /// After the causal pass, smooth every track over the whole recording (fixed-interval
    /// unscented RTS smoother, docs/smoothing.md) and print one more line per frame and
    /// leader (`"smoothed": true` with --json; see docs/outputs.md). Keeps every filter step
    /// in memory until the end.
    #[arg(long)]
    pub smooth: bool,
    /// Tracking-guided detection: search only where the tracker predicts each leader's rig
    /// (with a margin from the prediction's uncertainty), and scan the whole frame every
    /// --full-scan-every frames, when a track coasts and while nothing is tracked. Much
    /// faster on large frames (docs/tracking.md, docs/performance.md).
    #[arg(long)]
    pub guided: bool,
    /// With --guided: a full-frame scan at least every N frames, so that robots entering
    /// the view are picked up within N frames.
    #[arg(long, value_name = "N", requires = "guided", default_value_t = GuidedConfig::default().full_scan_period,
          value_parser = clap::value_parser!(u32).range(1..))]
    pub full_scan_every: u32,
    /// Also search large dark regions that gave no quad by AprilTag 3's boundary
    /// clustering, as `detect` does by default: reads markers that touch something as dark
    /// as their ink (a rig's tag against a dark floor or a shadow). Off by default in
    /// `track`: it costs about 3 ms more per 640x480 real frame, and 2-4x the detection
    /// time on cluttered frames (docs/marker-families.md).
    #[arg(long)]
    pub boundary_clusters: bool,
}
