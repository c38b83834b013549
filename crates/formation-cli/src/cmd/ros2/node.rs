//! `formation-tracker ros2`: the tracker as a ROS 2 node.

use std::collections::{HashMap, VecDeque};
use std::path::PathBuf;
use std::time::{Duration, Instant};

use clap::Args as ClapArgs;
use formation_io::frames::GreyImage;
use formation_ros2::convert::{self, FrameIds, LeaderMessages};
use formation_ros2::topics::{publisher, reliable, sensor_data, subscription};
use formation_ros2::{RosEnv, msg};
use formation_tracker::pipeline::PipelineFrame;
use formation_tracker::tracker::Status;
use ros2_client::dds::rustdds::mio1::{Events, Interest, Poll, Token};
use ros2_client::dds::{Publisher, Subscription};
use unicycle::{Inputs, SeparationBearingController};

use super::{InputsType, drain, stamp_ns};
use crate::cmd::track::RunArgs;
use crate::cmd::track::session::{FrameIn, Session};
use crate::cmd::{self, CliError, progress::errln};

/// Track leader robots live: camera frames and the follower's odometry from ROS 2 topics,
/// the leaders' poses, velocities and formation variables published back (docs/ros2.md).
///
/// Runs until SIGINT or SIGTERM (or --max-frames). The DDS domain is ROS_DOMAIN_ID (default
/// 0); ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST keeps every packet on the loopback
/// interface. Topic names are relative to --namespace unless they start with `/`. Prints
/// one line per frame on stdout, as `track` does (JSON with --json), and a summary on
/// stderr at the end.
#[derive(Debug, ClapArgs)]
pub struct Args {
    /// The node's namespace: relative topic names are resolved in it.
    #[arg(long, value_name = "NS", default_value = "/")]
    pub namespace: String,
    /// The node's name.
    #[arg(long, value_name = "NAME", default_value = "formation_tracker")]
    pub node_name: String,
    /// Camera frames: sensor_msgs/msg/Image (any encoding `track` reads from bags).
    #[arg(long, value_name = "TOPIC", default_value = "image_raw")]
    pub image_topic: String,
    /// Subscribe to sensor_msgs/msg/CompressedImage (JPEG or PNG) on
    /// IMAGE_TOPIC/compressed instead of raw images.
    #[arg(long)]
    pub compressed: bool,
    /// The camera's calibration (sensor_msgs/msg/CameraInfo); frames wait for the first one
    /// unless --camera gives a file.
    #[arg(long, value_name = "TOPIC", default_value = "camera_info")]
    pub camera_info_topic: String,
    /// Calibration file (OpenCV YAML or ROS camera_info) instead of the topic.
    #[arg(long, value_name = "FILE")]
    pub camera: Option<PathBuf>,
    /// The follower's own inputs `(v2, w2)` (the twist of its odometry).
    #[arg(long, value_name = "TOPIC", default_value = "odom")]
    pub inputs_topic: String,
    /// The inputs topic's type; `none` takes the follower as standing still.
    #[arg(long, value_enum, value_name = "TYPE", default_value = "odometry")]
    pub inputs_type: InputsType,
    /// Prefix of the published topics: PREFIX/leader_N/pose, .../pose_base, .../twist,
    /// .../formation, PREFIX/annotations.
    #[arg(long, value_name = "PREFIX", default_value = "formation")]
    pub output_prefix: String,
    /// The follower's body frame (parent of the leaders' frames on /tf).
    #[arg(long, value_name = "FRAME", default_value = "base_link")]
    pub base_frame: String,
    /// Prefix of the leaders' body frames: leader_1, leader_2, ...
    #[arg(long, value_name = "PREFIX", default_value = "leader_")]
    pub leader_frame_prefix: String,
    /// Nominal frame rate of the camera, frames/s (the tracker's nominal step; times come
    /// from the image stamps).
    #[arg(long, value_name = "F", default_value_t = 30.0, value_parser = crate::cmd::numbers::fps)]
    pub fps: f64,
    /// Drive the follower: run the separation-bearing controller of FILE (the `track
    /// --controller` file: leader, set-points, gains, limits) on the tracked estimate and
    /// publish geometry_msgs/msg/Twist on --cmd-vel-topic. The tracker is told the
    /// controller, as with `track --controller`.
    #[arg(long, value_name = "FILE", conflicts_with = "controller")]
    pub control: Option<PathBuf>,
    /// Where --control publishes the follower's commands.
    #[arg(long, value_name = "TOPIC", default_value = "cmd_vel")]
    pub cmd_vel_topic: String,
    /// With --control: seconds without a measurement of the leader after which the
    /// follower is stopped (zero twist) until the leader is seen again. The default is
    /// `track`'s --lost-after: the tracker coasts through shorter gaps.
    #[arg(long, value_name = "S", default_value_t = 2.0, value_parser = crate::cmd::numbers::positive)]
    pub stop_after: f64,
    /// Leaders whose topics exist from the start (comma-separated robot ids; the --control
    /// leader is added). Another leader gets its topics when first seen, and a subscriber
    /// may miss its first messages: DDS matches a new writer with known readers only after
    /// it is made.
    #[arg(long, value_name = "IDS", value_delimiter = ',', default_value = "1")]
    pub leaders: Vec<u32>,
    /// Exit after this many frames are tracked (scripts and tests); default: run until
    /// interrupted.
    #[arg(long, value_name = "N")]
    pub max_frames: Option<u64>,
    /// Outputs, rig, mount and tracking options, as for `track`.
    #[command(flatten)]
    pub run: RunArgs,
}

/// The image subscription.
enum Images {
    Raw(Subscription<msg::Image>),
    Compressed(Subscription<msg::CompressedImage>),
}

/// A received frame, before decoding.
enum Received {
    Raw(msg::Image),
    Compressed(msg::CompressedImage),
}

impl Received {
    fn header(&self) -> &msg::Header {
        match self {
            Received::Raw(m) => &m.header,
            Received::Compressed(m) => &m.header,
        }
    }
}

/// The inputs subscription.
enum InputsSub {
    Odometry(Subscription<msg::Odometry>),
    Stamped(Subscription<msg::TwistStamped>),
    Twist(Subscription<msg::Twist>),
    None,
}

/// One leader's publishers.
struct LeaderPubs {
    pose: Publisher<msg::PoseWithCovarianceStamped>,
    pose_base: Publisher<msg::PoseWithCovarianceStamped>,
    twist: Publisher<msg::TwistWithCovarianceStamped>,
    formation: Publisher<msg::Float64MultiArray>,
}

/// One inputs message: `(v2, w2)`, or why it is unusable.
type InputsResult = Result<(f64, f64), String>;

/// The node's counts (diagnostics and the final summary).
#[derive(Debug, Default, Clone, Copy)]
struct Counts {
    received: u64,
    tracked: u64,
    /// Taken but skipped because a newer frame was waiting.
    skipped: u64,
    /// Missing from the publishers' sequence numbers (overwritten in the reader's queue or
    /// lost on the way).
    missed: u64,
    /// Unusable: no calibration yet, undecodable, a bad stamp, out of order.
    bad: u64,
    bad_inputs: u64,
}

const IMAGES: Token = Token(0);
const INFO: Token = Token(1);
const INPUTS: Token = Token(2);

/// Runs the node.
pub fn run(args: Args) -> Result<(), CliError> {
    cmd::interrupt::install()?;
    let env = RosEnv::from_env()?;
    let mut run_args = args.run.clone();
    let controller = match &args.control {
        Some(path) => {
            let own = formation_io::controller::load(path)?;
            SeparationBearingController::new(run_args.mount_offset, own.controller)
                .map_err(|e| format!("{}: {e}", path.display()))?;
            run_args.controller = Some(path.clone());
            Some(own)
        }
        None => None,
    };
    let mut node = env.node(&args.namespace, &args.node_name)?;
    let image_topic = if args.compressed {
        format!("{}/compressed", args.image_topic)
    } else {
        args.image_topic.clone()
    };
    // The reader keeps a few frames: those that arrive while one is processed are taken
    // and skipped (counted), never queued without bound.
    let images = if args.compressed {
        Images::Compressed(subscription(&mut node, &image_topic, &sensor_data(4))?)
    } else {
        Images::Raw(subscription(&mut node, &image_topic, &sensor_data(4))?)
    };
    let info: Subscription<msg::CameraInfo> =
        subscription(&mut node, &args.camera_info_topic, &sensor_data(1))?;
    let q = sensor_data(50);
    let inputs = match args.inputs_type {
        InputsType::Odometry => {
            InputsSub::Odometry(subscription(&mut node, &args.inputs_topic, &q)?)
        }
        InputsType::TwistStamped => {
            InputsSub::Stamped(subscription(&mut node, &args.inputs_topic, &q)?)
        }
        InputsType::Twist => InputsSub::Twist(subscription(&mut node, &args.inputs_topic, &q)?),
        InputsType::None => InputsSub::None,
    };
    let mut poll = Poll::new().map_err(|e| format!("cannot poll: {e}"))?;
    let reg = |r: std::io::Result<()>| r.map_err(|e| format!("cannot poll: {e}"));
    let mut images = images;
    match &mut images {
        Images::Raw(s) => reg(poll.registry().register(s, IMAGES, Interest::READABLE))?,
        Images::Compressed(s) => reg(poll.registry().register(s, IMAGES, Interest::READABLE))?,
    }
    let mut info = info;
    reg(poll
        .registry()
        .register(&mut info, INFO, Interest::READABLE))?;
    let mut inputs = inputs;
    match &mut inputs {
        InputsSub::Odometry(s) => reg(poll.registry().register(s, INPUTS, Interest::READABLE))?,
        InputsSub::Stamped(s) => reg(poll.registry().register(s, INPUTS, Interest::READABLE))?,
        InputsSub::Twist(s) => reg(poll.registry().register(s, INPUTS, Interest::READABLE))?,
        InputsSub::None => {}
    }
    let out = reliable(10);
    let tf: Publisher<msg::TfMessage> = publisher(&mut node, "/tf", &reliable(100))?;
    let annotations: Publisher<msg::ImageAnnotations> = publisher(
        &mut node,
        &format!("{}/annotations", args.output_prefix),
        &out,
    )?;
    let diagnostics: Publisher<msg::DiagnosticArray> = publisher(&mut node, "/diagnostics", &out)?;
    let cmd_vel: Option<Publisher<msg::Twist>> = match &controller {
        Some(_) => Some(publisher(&mut node, &args.cmd_vel_topic, &out)?),
        None => None,
    };
    let mut leaders = HashMap::new();
    let wanted = args
        .leaders
        .iter()
        .copied()
        .chain(controller.as_ref().map(|c| c.leader));
    for robot in wanted {
        if let std::collections::hash_map::Entry::Vacant(v) = leaders.entry(robot) {
            v.insert(leader_publishers(&mut node, &args.output_prefix, robot)?);
        }
    }
    let calibration = args
        .camera
        .as_deref()
        .map(cmd::load_calibration)
        .transpose()?;
    errln!(
        "ros2: node {} in domain {}{}: images on {image_topic}, calibration {}, inputs {}",
        args.node_name,
        env.domain_id,
        if env.range == formation_ros2::DiscoveryRange::Localhost {
            " (localhost only)"
        } else {
            ""
        },
        args.camera.as_ref().map_or_else(
            || format!("on {}", args.camera_info_topic),
            |p| p.display().to_string()
        ),
        match args.inputs_type {
            InputsType::None => "none (standing still)".to_owned(),
            _ => format!("on {}", args.inputs_topic),
        }
    );
    let mut state = NodeState {
        args: &args,
        run: &run_args,
        calibration,
        session: None,
        grey: GreyImage::default(),
        inputs: VecDeque::new(),
        first_stamp: None,
        last_stamp: None,
        last_seq: None,
        counts: Counts::default(),
        leaders,
        seen: std::collections::BTreeSet::new(),
        latencies: Histogram::new(),
        stages: std::array::from_fn(|_| Histogram::new()),
        window: Histogram::new(),
        said: HashMap::new(),
        last_seen: None,
        frames: FrameIds {
            base: args.base_frame.clone(),
            camera: String::new(),
            leader_prefix: args.leader_frame_prefix.clone(),
        },
        controller,
        stopped: true,
        last_seen_wall: None,
        node,
    };
    let mut events = Events::with_capacity(16);
    let mut next_diag = Instant::now() + Duration::from_secs(1);
    let mut window_counts = state.counts;
    let mut batch = Vec::new();
    while cmd::interrupt::requested().is_none()
        && args.max_frames.is_none_or(|m| state.counts.tracked < m)
    {
        // Wake at least every 50 ms: signals, diagnostics and the stop timer.
        if let Err(e) = poll.poll(&mut events, Some(Duration::from_millis(50)))
            && e.kind() != std::io::ErrorKind::Interrupted
        {
            return Err(format!("cannot poll: {e}").into());
        }
        // Calibration and inputs first, so that a frame finds what arrived before it.
        let mut infos = Vec::new();
        drain(&info, |m| m, &mut infos);
        for m in infos {
            state.camera_info(m);
        }
        state.take_inputs(&inputs);
        let arrived = Instant::now();
        batch.clear();
        match &images {
            Images::Raw(s) => drain(s, Received::Raw, &mut batch),
            Images::Compressed(s) => drain(s, Received::Compressed, &mut batch),
        }
        let taken = Instant::now();
        if let Some(newest) = state.newest(&mut batch) {
            let topic = image_topic.as_str();
            if let Some((done, stamp)) = state.track(newest, topic)? {
                let tracked = Instant::now();
                state.publish(&done, stamp, &tf, &annotations, cmd_vel.as_ref())?;
                let ms = |from: Instant, to: Instant| (to - from).as_secs_f64() * 1e3;
                let now = Instant::now();
                state.latencies.add(ms(arrived, now));
                state.window.add(ms(arrived, now));
                let stages = [
                    ms(arrived, taken),
                    ms(taken, tracked) - done.timing.total_ms(),
                    done.timing.total_ms(),
                    ms(tracked, now),
                ];
                for (h, v) in state.stages.iter_mut().zip(stages) {
                    h.add(v);
                }
            }
        }
        if let (Some(p), Some(_)) = (&cmd_vel, &state.controller) {
            state.stop_if_lost(p);
        }
        if Instant::now() >= next_diag {
            diagnostics
                .publish(state.diagnostics(&window_counts))
                .map_err(|e| format!("cannot publish /diagnostics: {e:?}"))?;
            window_counts = state.counts;
            state.window.clear();
            next_diag += Duration::from_secs(1);
        }
    }
    if let Some(p) = &cmd_vel {
        // Stop the robot on the way out; twice, in case a best-effort reader loses one.
        for _ in 0..2 {
            let _ = p.publish(msg::Twist::default());
        }
    }
    // Reliable writers resend what a reader missed while the participant lives: let the
    // last frame's messages (and the stop) reach their readers before it goes away.
    std::thread::sleep(Duration::from_millis(300));
    state.finish()
}

/// The publishers of leader `robot`'s topics.
fn leader_publishers(
    node: &mut ros2_client::dds::Node,
    prefix: &str,
    robot: u32,
) -> Result<LeaderPubs, CliError> {
    let base = format!("{prefix}/leader_{robot}");
    let q = reliable(10);
    Ok(LeaderPubs {
        pose: publisher(node, &format!("{base}/pose"), &q)?,
        pose_base: publisher(node, &format!("{base}/pose_base"), &q)?,
        twist: publisher(node, &format!("{base}/twist"), &q)?,
        formation: publisher(node, &format!("{base}/formation"), &q)?,
    })
}

/// Everything the node's loop carries between frames.
struct NodeState<'a> {
    args: &'a Args,
    run: &'a RunArgs,
    calibration: Option<pose::Camera>,
    session: Option<Session<'a>>,
    grey: GreyImage,
    /// Recent follower inputs: (stamp in ns, if the message had one; v2; w2).
    inputs: VecDeque<(Option<u64>, f64, f64)>,
    first_stamp: Option<u64>,
    last_stamp: Option<u64>,
    /// The last image sequence number seen (one camera publisher).
    last_seq: Option<i64>,
    counts: Counts,
    leaders: HashMap<u32, LeaderPubs>,
    /// The leaders tracked so far.
    seen: std::collections::BTreeSet<u32>,
    /// Arrival-to-publication times of every tracked frame.
    latencies: Histogram,
    /// The same over the current diagnostics period.
    window: Histogram,
    /// Per tracked frame: taking the image (deserialising), decoding and the stdout line,
    /// the pipeline, publishing.
    stages: [Histogram; 4],
    /// How many times each kind of problem was reported (the first few are printed).
    said: HashMap<&'static str, u64>,
    /// Stamp of the last frame in which the controlled leader was measured, ns.
    last_seen: Option<u64>,
    frames: FrameIds,
    controller: Option<formation_io::controller::FollowerController>,
    /// Whether the last command sent was a stop.
    stopped: bool,
    /// When the controlled leader was last measured recently enough to drive on.
    last_seen_wall: Option<Instant>,
    /// The node (publishers for new leaders are made as they appear).
    node: ros2_client::dds::Node,
}

impl<'a> NodeState<'a> {
    /// Prints one line about a problem of `kind`: the first five, then every 100th.
    fn warn(&mut self, kind: &'static str, line: &str) {
        let n = self.said.entry(kind).or_insert(0);
        *n += 1;
        if *n <= 5 || n.is_multiple_of(100) {
            let more = if *n == 5 {
                " (further ones: every 100th)"
            } else {
                ""
            };
            match &self.session {
                Some(s) => s.progress.println(&format!("ros2: {line}{more}")),
                None => errln!("ros2: {line}{more}"),
            }
        }
    }

    fn camera_info(&mut self, m: Result<(msg::CameraInfo, i64), String>) {
        let info = match m {
            Ok((info, _)) => info,
            Err(e) => return self.warn("camera_info", &format!("unreadable CameraInfo: {e}")),
        };
        if self.args.camera.is_some() {
            return;
        }
        match convert::calibration(&info) {
            Ok(c) => {
                if self.calibration.is_none() {
                    errln!(
                        "ros2: calibration from {} ({}x{})",
                        self.args.camera_info_topic,
                        c.width,
                        c.height
                    );
                    self.calibration = Some(c);
                } else if self.calibration != Some(c) {
                    self.warn(
                        "camera_info_changed",
                        "CameraInfo changed; the first one stays in use",
                    );
                }
            }
            Err(e) => self.warn("camera_info", &e.to_string()),
        }
    }

    fn take_inputs(&mut self, sub: &InputsSub) {
        let got = match sub {
            InputsSub::Odometry(s) => {
                inputs_of(s, "Odometry", |m| (m.header.stamp.to_ns(), &m.twist.twist))
            }
            InputsSub::Stamped(s) => {
                inputs_of(s, "TwistStamped", |m| (m.header.stamp.to_ns(), &m.twist))
            }
            InputsSub::Twist(s) => inputs_of(s, "Twist", |m| (None, m)),
            InputsSub::None => Vec::new(),
        };
        for (stamp, r) in got {
            match r {
                Ok((v, w)) => {
                    self.inputs.push_back((stamp, v, w));
                    if self.inputs.len() > 256 {
                        self.inputs.pop_front();
                    }
                }
                Err(e) => {
                    self.counts.bad_inputs += 1;
                    self.warn("inputs", &format!("{e}; the previous inputs stay in force"));
                }
            }
        }
    }

    /// The follower's inputs at `stamp`: the latest stamped sample not after it (else the
    /// latest received), or standing still before any.
    fn inputs_at(&self, stamp: u64) -> Inputs {
        let stamped = self
            .inputs
            .iter()
            .rev()
            .find(|(s, _, _)| s.is_none_or(|s| s <= stamp));
        match stamped.or(self.inputs.back()) {
            Some(&(_, v, w)) => Inputs::new(v, w),
            None => Inputs::new(0.0, 0.0),
        }
    }

    /// The newest frame of `batch` (counting the others as skipped, the gaps in sequence
    /// numbers as missed, and unreadable samples as bad).
    fn newest(
        &mut self,
        batch: &mut Vec<Result<(Received, i64), String>>,
    ) -> Option<(Received, i64)> {
        let mut newest = None;
        let n = batch.len();
        for (i, r) in batch.drain(..).enumerate() {
            match r {
                Ok((m, seq)) => {
                    self.counts.received += 1;
                    // One publisher per camera: a sequence number that goes back starts a
                    // new publisher.
                    let last = self.last_seq.replace(seq);
                    if let Some(last) = last
                        && seq > last + 1
                    {
                        self.counts.missed += u64::try_from(seq - last - 1).unwrap_or(0);
                    }
                    if i + 1 < n {
                        self.counts.skipped += 1;
                    } else {
                        newest = Some((m, seq));
                    }
                }
                Err(e) => {
                    self.counts.bad += 1;
                    self.warn("image", &format!("unreadable image message: {e}"));
                }
            }
        }
        newest
    }

    /// Decodes and tracks one frame; `None` for a frame that could not be used (reported).
    fn track(
        &mut self,
        (m, seq): (Received, i64),
        topic: &str,
    ) -> Result<Option<(PipelineFrame, msg::Time)>, CliError> {
        let Some(calibration) = self.calibration else {
            self.counts.bad += 1;
            self.warn(
                "no_calibration",
                "a frame before any CameraInfo: dropped (waiting for the calibration)",
            );
            return Ok(None);
        };
        let header = m.header().clone();
        let stamp = match stamp_ns(&header, "image") {
            Ok(s) => s,
            Err(e) => {
                self.counts.bad += 1;
                self.warn("stamp", &e);
                return Ok(None);
            }
        };
        if self.last_stamp.is_some_and(|last| stamp <= last) {
            self.counts.bad += 1;
            self.warn(
                "order",
                &format!("image stamp {stamp} ns is not after the previous frame's: dropped"),
            );
            return Ok(None);
        }
        let max_side = self.run.max_side;
        let decoded = match &m {
            Received::Raw(img) => convert::image_to_grey(img, &mut self.grey, max_side),
            Received::Compressed(img) => convert::compressed_to_grey(img, &mut self.grey, max_side),
        };
        if let Err(e) = decoded {
            self.counts.bad += 1;
            self.warn("decode", &format!("frame {seq}: {e}"));
            return Ok(None);
        }
        if self.frames.camera.is_empty() {
            self.frames.camera = if header.frame_id.is_empty() {
                "camera".into()
            } else {
                header.frame_id.clone()
            };
        }
        let first = *self.first_stamp.get_or_insert(stamp);
        self.last_stamp = Some(stamp);
        let t = (stamp - first) as f64 * 1e-9;
        let follower = self.inputs_at(stamp);
        let run = self.run;
        let session = match &mut self.session {
            Some(s) => s,
            None => self.session.insert(Session::new(run, calibration, None)?),
        };
        session.progress.inc();
        let index = self.counts.tracked;
        let input = FrameIn {
            index,
            source: format!("{topic}#{seq}"),
            t,
            follower,
            pan: run.pan,
            image: &self.grey,
            stamp_ns: stamp,
            bag: None,
        };
        let fps = self.args.fps;
        match session.frame(input, || Ok(fps))? {
            Some(done) => {
                self.counts.tracked += 1;
                Ok(Some((done, header.stamp)))
            }
            None => {
                self.counts.bad += 1;
                Ok(None)
            }
        }
    }

    /// Publishes one tracked frame: per leader its poses, twist and formation, `/tf`, the
    /// annotations, and with `--control` the follower's command.
    fn publish(
        &mut self,
        done: &PipelineFrame,
        stamp: msg::Time,
        tf: &Publisher<msg::TfMessage>,
        annotations: &Publisher<msg::ImageAnnotations>,
        cmd_vel: Option<&Publisher<msg::Twist>>,
    ) -> Result<(), CliError> {
        let Some(session) = &self.session else {
            return Ok(());
        };
        let mount = session.mount();
        let marks = session
            .pipeline()
            .map(|p| annotations_of(p.markers(), stamp));
        let mut transforms = Vec::new();
        let mut failed = Vec::new();
        for report in &done.report.leaders {
            let m: LeaderMessages =
                match convert::leader_messages(report, &mount, stamp, &self.frames) {
                    Ok(m) => m,
                    Err(e) => {
                        failed.push(format!("robot {}: {e}", report.robot));
                        continue;
                    }
                };
            self.seen.insert(report.robot);
            let pubs = match self.leaders.entry(report.robot) {
                std::collections::hash_map::Entry::Occupied(o) => o.into_mut(),
                std::collections::hash_map::Entry::Vacant(v) => v.insert(leader_publishers(
                    &mut self.node,
                    &self.args.output_prefix,
                    report.robot,
                )?),
            };
            let sent = [
                pubs.pose
                    .publish(m.pose_camera)
                    .map_err(|e| format!("{e:?}")),
                pubs.pose_base
                    .publish(m.pose_base)
                    .map_err(|e| format!("{e:?}")),
                pubs.twist.publish(m.twist).map_err(|e| format!("{e:?}")),
                pubs.formation
                    .publish(m.variables)
                    .map_err(|e| format!("{e:?}")),
            ];
            if let Some(Err(e)) = sent.into_iter().find(Result::is_err) {
                failed.push(format!("robot {}: cannot publish: {e}", report.robot));
            }
            transforms.push(m.transform);
        }
        for f in failed {
            self.warn("publish", &f);
        }
        if !transforms.is_empty() {
            tf.publish(msg::TfMessage { transforms })
                .map_err(|e| format!("cannot publish /tf: {e:?}"))?;
        }
        if let Some(a) = marks
            && let Err(e) = annotations.publish(a)
        {
            self.warn("publish", &format!("cannot publish the annotations: {e:?}"));
        }
        if let (Some(p), Some(own)) = (cmd_vel, &self.controller) {
            let report = done
                .report
                .leaders
                .iter()
                .find(|l| l.robot == own.leader && l.status != Status::Lost);
            let now = stamp.to_ns().unwrap_or(0);
            if report.is_some_and(|l| l.status == Status::Tracking) {
                self.last_seen = Some(now);
            }
            let fresh = self
                .last_seen
                .is_some_and(|s| (now.saturating_sub(s)) as f64 * 1e-9 <= self.args.stop_after);
            // The set-points in force at this frame's time (from the first frame).
            let t = now.saturating_sub(self.first_stamp.unwrap_or(now)) as f64 * 1e-9;
            let command = match report {
                Some(l) if fresh => SeparationBearingController::new(mount.offset, own.at(t))
                    .and_then(|law| law.inputs(&l.formation, Inputs::new(l.v1, l.w1)))
                    .map_err(|e| format!("controller: {e}")),
                _ => Ok(Inputs::new(0.0, 0.0)),
            };
            let command = match command {
                Ok(c) => c,
                Err(e) => {
                    self.warn("control", &format!("{e}: stopping"));
                    Inputs::new(0.0, 0.0)
                }
            };
            if fresh {
                self.last_seen_wall = Some(Instant::now());
            }
            self.stopped = command.v == 0.0 && command.w == 0.0;
            p.publish(twist_of(command))
                .map_err(|e| format!("cannot publish {}: {e:?}", self.args.cmd_vel_topic))?;
        }
        Ok(())
    }
}

impl NodeState<'_> {
    /// With `--control`: stops the follower when no frame has shown the leader for
    /// `--stop-after` seconds of wall time (the camera stalled, or every frame is dropped).
    fn stop_if_lost(&mut self, p: &Publisher<msg::Twist>) {
        let stale = self
            .last_seen_wall
            .is_none_or(|t| t.elapsed().as_secs_f64() > self.args.stop_after);
        if stale && !self.stopped {
            if let Err(e) = p.publish(msg::Twist::default()) {
                self.warn("publish", &format!("cannot publish the stop: {e:?}"));
            } else {
                self.stopped = true;
            }
        }
    }

    /// The diagnostics of the period since `before`.
    fn diagnostics(&self, before: &Counts) -> msg::DiagnosticArray {
        let c = &self.counts;
        let tracked = c.tracked - before.tracked;
        let dropped = (c.skipped + c.missed) - (before.skipped + before.missed);
        let bad = c.bad - before.bad;
        let (median, p99) = (self.window.quantile(0.5), self.window.quantile(0.99));
        let leaders = self.seen.len();
        let (level, message) = if tracked == 0 {
            (1, "no frame tracked in the last second".to_owned())
        } else if dropped > 0 || bad > 0 {
            (
                1,
                format!("{dropped} frames dropped, {bad} unusable in the last second"),
            )
        } else {
            (0, format!("tracking at {tracked} frames/s"))
        };
        let kv = |k: &str, v: String| msg::KeyValue {
            key: k.to_owned(),
            value: v,
        };
        let now = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| u64::try_from(d.as_nanos()).unwrap_or(u64::MAX));
        msg::DiagnosticArray {
            header: msg::Header {
                stamp: msg::Time::from_ns(now),
                frame_id: String::new(),
            },
            status: vec![msg::DiagnosticStatus {
                level,
                name: format!("{}: tracking", self.args.node_name),
                message,
                hardware_id: self.frames.camera.clone(),
                values: vec![
                    kv("frames_per_second", tracked.to_string()),
                    kv("latency_median_ms", format!("{median:.3}")),
                    kv("latency_p99_ms", format!("{p99:.3}")),
                    kv("frames_received", c.received.to_string()),
                    kv("frames_tracked", c.tracked.to_string()),
                    kv("frames_dropped", (c.skipped + c.missed).to_string()),
                    kv("frames_unusable", c.bad.to_string()),
                    kv("inputs_unusable", c.bad_inputs.to_string()),
                    kv("leaders_seen", leaders.to_string()),
                ],
            }],
        }
    }

    /// Ends the run: the session's end (stdout flushed, `--mcap` kept) and the summary.
    fn finish(self) -> Result<(), CliError> {
        let c = self.counts;
        let (median, p99) = (self.latencies.quantile(0.5), self.latencies.quantile(0.99));
        let stage = |i: usize| self.stages[i].quantile(0.5);
        let summary = format!(
            "{} frames tracked of {} received; {} dropped ({} skipped while busy, {} missing from the sequence), {} unusable, {} unusable inputs; latency from arrival to publication: median {median:.2} ms, 99th percentile {p99:.2} ms (medians: taking the image {:.2} ms, decoding and the stdout line {:.2} ms, pipeline {:.2} ms, publishing {:.2} ms)",
            c.tracked,
            c.received,
            c.skipped + c.missed,
            c.skipped,
            c.missed,
            c.bad,
            c.bad_inputs,
            stage(0),
            stage(1),
            stage(2),
            stage(3)
        );
        if let Some(session) = self.session {
            match session.finish(|t| (t * self.args.fps).round() as u64) {
                Ok(_) => {}
                // SIGINT and SIGTERM are how a node is stopped: not an error.
                Err(e) if e.downcast_ref::<cmd::interrupt::Interrupted>().is_some() => {}
                Err(e) => return Err(e),
            }
        }
        errln!("ros2: {summary}");
        Ok(())
    }
}

/// Every inputs message waiting on `sub`: its stamp (if the type has one) and `(v2, w2)`, or
/// why it is unusable.
fn inputs_of<M: serde::de::DeserializeOwned + 'static>(
    sub: &Subscription<M>,
    kind: &'static str,
    twist: impl Fn(&M) -> (Option<u64>, &msg::Twist),
) -> Vec<(Option<u64>, InputsResult)> {
    let mut taken = Vec::new();
    drain(sub, |m| m, &mut taken);
    taken
        .into_iter()
        .map(|m| match m {
            Ok((m, _)) => {
                let (stamp, t) = twist(&m);
                (
                    stamp,
                    convert::follower_inputs(kind, t).map_err(|e| e.to_string()),
                )
            }
            Err(e) => (None, Err(format!("unreadable {kind}: {e}"))),
        })
        .collect()
}

/// Times in milliseconds, counted in 10 us bins up to 100 ms (and one bin beyond): the
/// percentiles of a run of any length in fixed memory (a node runs for days).
#[derive(Debug, Clone)]
struct Histogram {
    bins: Vec<u64>,
    n: u64,
}

impl Histogram {
    const BIN_MS: f64 = 0.01;
    const BINS: usize = 10_000;

    fn new() -> Self {
        Self {
            bins: vec![0; Self::BINS + 1],
            n: 0,
        }
    }

    /// Empties the histogram, keeping its bins' memory.
    fn clear(&mut self) {
        self.bins.fill(0);
        self.n = 0;
    }

    fn add(&mut self, ms: f64) {
        let bin = (ms.max(0.0) / Self::BIN_MS) as usize;
        self.bins[bin.min(Self::BINS)] += 1;
        self.n += 1;
    }

    /// The `q` quantile (nearest rank), as the middle of its bin; 0 when empty.
    fn quantile(&self, q: f64) -> f64 {
        if self.n == 0 {
            return 0.0;
        }
        let rank = ((self.n - 1) as f64 * q).round() as u64;
        let mut below = 0;
        for (i, &c) in self.bins.iter().enumerate() {
            below += c;
            if below > rank {
                return (i as f64 + 0.5) * Self::BIN_MS;
            }
        }
        (Self::BINS as f64 + 0.5) * Self::BIN_MS
    }
}

fn twist_of(c: Inputs) -> msg::Twist {
    msg::Twist {
        linear: msg::Vector3 {
            x: c.v,
            ..msg::Vector3::default()
        },
        angular: msg::Vector3 {
            z: c.w,
            ..msg::Vector3::default()
        },
    }
}

/// The markers read in a frame, as outlines with their dictionary index.
fn annotations_of(
    markers: &[formation_tracker::robots::MarkerObservation],
    stamp: msg::Time,
) -> msg::ImageAnnotations {
    let green = msg::Color {
        r: 0.1,
        g: 0.9,
        b: 0.2,
        a: 1.0,
    };
    let mut a = msg::ImageAnnotations::default();
    for m in markers {
        a.points.push(msg::PointsAnnotation {
            timestamp: stamp,
            r#type: 2,
            points: m
                .corners
                .iter()
                .map(|c| msg::Point2 { x: c.x, y: c.y })
                .collect(),
            outline_color: green,
            thickness: 2.0,
            ..msg::PointsAnnotation::default()
        });
        a.texts.push(msg::TextAnnotation {
            timestamp: stamp,
            position: msg::Point2 {
                x: m.corners[0].x,
                y: m.corners[0].y,
            },
            text: m.index.to_string(),
            font_size: 14.0,
            text_color: green,
            ..msg::TextAnnotation::default()
        });
    }
    a
}

#[cfg(test)]
mod tests {
    use super::Histogram;

    #[test]
    fn histogram_quantiles_are_the_nearest_ranks_to_a_bin() {
        let mut h = Histogram::new();
        assert_eq!(h.quantile(0.5), 0.0);
        for i in 1..=100 {
            h.add(f64::from(i) * 0.1);
        }
        // Nearest rank of 1..100 x 0.1 ms: the median is the 51st value (5.1 ms), the 99th
        // percentile the 99th (9.9 ms); each read back within half a bin.
        assert!(
            (h.quantile(0.5) - 5.1).abs() <= 0.005 + 1e-12,
            "{}",
            h.quantile(0.5)
        );
        assert!(
            (h.quantile(0.99) - 9.9).abs() <= 0.005 + 1e-12,
            "{}",
            h.quantile(0.99)
        );
        // Beyond the last bin, and below zero, values are kept at the ends.
        h.add(1e6);
        h.add(-1.0);
        assert_eq!(h.n, 102);
        assert!(h.quantile(1.0) > 100.0);
        assert!(h.quantile(0.0) < 0.01);
        h.clear();
        assert_eq!(h.quantile(0.5), 0.0);
        h.add(2.0);
        assert!(
            (h.quantile(0.5) - 2.005).abs() < 1e-9,
            "{}",
            h.quantile(0.5)
        );
    }
}
