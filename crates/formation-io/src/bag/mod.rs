//! ROS 2 bags (rosbag2's MCAP storage) as a frame source: a single `.mcap` file, or a
//! rosbag2 folder (`metadata.yaml` and one or more split `.mcap` files).
//!
//! - [`mcap`]: a streaming MCAP reader (one chunk in memory at a time; zstd and lz4 chunks
//!   decoded in pure Rust).
//! - [`cdr`]: ROS 2 CDR for the message types read (`sensor_msgs/msg/Image`,
//!   `CompressedImage`, `CameraInfo`, `nav_msgs/msg/Odometry`, `geometry_msgs/msg/Twist`,
//!   `TwistStamped`) and the one written (`Image`).
//! - [`pixels`]: image encodings to grey, and `CameraInfo` to a calibration.
//!
//! [`Bag::open`] reads what the files' summaries say (topics, types, message counts); a file
//! without a summary is scanned once for its channels. [`Bag::frames`] then streams the
//! image topic's frames in `header.stamp` order through a reorder window of
//! [`REORDER_WINDOW`] frames, each with the follower's inputs as of its stamp, and counts
//! what was irregular in [`BagStats`]. Memory: one MCAP record plus one decompressed chunk
//! (each at most [`mcap::max_record`], in practice rosbag2's chunk size, about 1 MiB), plus
//! `REORDER_WINDOW + 1` grey frames, whatever the bag's size.

pub mod cdr;
pub mod mcap;
pub mod pixels;

use std::cmp::Reverse;
use std::collections::{BTreeMap, BinaryHeap, VecDeque};
use std::path::{Path, PathBuf};

use self::mcap::{McapError, McapReader};
use crate::frames::GreyImage;

/// Frames held back to put messages recorded out of order back in `header.stamp` order.
pub const REORDER_WINDOW: usize = 8;

/// `sensor_msgs/msg/Image`.
pub const IMAGE: &str = "sensor_msgs/msg/Image";
/// `sensor_msgs/msg/CompressedImage`.
pub const COMPRESSED_IMAGE: &str = "sensor_msgs/msg/CompressedImage";
/// `sensor_msgs/msg/CameraInfo`.
pub const CAMERA_INFO: &str = "sensor_msgs/msg/CameraInfo";

/// Errors of a bag. Every message error names its topic and the message's index on it.
#[derive(Debug, thiserror::Error)]
pub enum BagError {
    /// The path cannot be read.
    #[error("cannot open bag {path}: {source}")]
    Open {
        /// The path.
        path: PathBuf,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
    /// `metadata.yaml` names a file outside the bag folder, or cannot be read.
    #[error("{path}: {reason}")]
    Metadata {
        /// The `metadata.yaml` file.
        path: PathBuf,
        /// What is wrong, naming the field and value.
        reason: String,
    },
    /// A folder without `.mcap` files.
    #[error("{path} holds no .mcap file (a rosbag2 folder has metadata.yaml and its .mcap files)")]
    NoMcap {
        /// The folder.
        path: PathBuf,
    },
    /// The MCAP container is broken (truncated, bad CRC, ...). The stream ends here.
    #[error("{source}{after}")]
    Mcap {
        /// The reader's error.
        #[source]
        source: McapError,
        /// `" (after message N of /topic)"` when frames were read before.
        after: String,
    },
    /// A topic choice that cannot be made.
    #[error("{0}")]
    Topic(String),
    /// One message could not be used.
    #[error("topic {topic}, message {index}: {reason}")]
    Message {
        /// The topic.
        topic: String,
        /// The message's index on its topic, from 0.
        index: u64,
        /// What is wrong.
        reason: String,
        /// Whether the stream ends here (a wrong type or encoding on the topic).
        fatal: bool,
    },
}

impl BagError {
    /// Whether the stream cannot go on after this error.
    pub fn is_fatal(&self) -> bool {
        !matches!(self, Self::Message { fatal: false, .. })
    }
}

/// A topic of the bag.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Topic {
    /// Message type (schema name), e.g. `sensor_msgs/msg/Image`.
    pub type_name: String,
    /// Message encoding, e.g. `cdr`.
    pub encoding: String,
    /// Messages on it, when the summaries say.
    pub count: Option<u64>,
}

/// A rosbag2 MCAP bag: its files in order and its topics.
#[derive(Debug, Clone)]
pub struct Bag {
    files: Vec<PathBuf>,
    /// Split files `metadata.yaml` lists that are not there.
    missing: Vec<PathBuf>,
    topics: BTreeMap<String, Topic>,
}

/// Whether `path` looks like a bag: an `.mcap` file or a folder with `metadata.yaml` or
/// `.mcap` files.
pub fn is_bag(path: &Path) -> bool {
    if path.is_dir() {
        return path.join("metadata.yaml").is_file() || !mcap_files(path).is_empty();
    }
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("mcap"))
}

fn mcap_files(dir: &Path) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .map(|entries| {
            entries
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.extension().is_some_and(|e| e == "mcap") && p.is_file())
                .collect()
        })
        .unwrap_or_default();
    // rosbag2 names splits `NAME_0.mcap`, `NAME_1.mcap`, ..., `NAME_10.mcap`: order by the
    // number, not the text.
    files.sort_by_key(|p| {
        let stem = p.file_stem().and_then(|s| s.to_str()).unwrap_or("");
        let digits: String = stem
            .chars()
            .rev()
            .take_while(char::is_ascii_digit)
            .collect::<Vec<_>>()
            .into_iter()
            .rev()
            .collect();
        (
            stem[..stem.len() - digits.len()].to_owned(),
            digits.parse::<u64>().unwrap_or(0),
        )
    });
    files
}

#[derive(serde::Deserialize)]
struct Metadata {
    rosbag2_bagfile_information: Option<MetadataInfo>,
}

#[derive(serde::Deserialize)]
struct MetadataInfo {
    relative_file_paths: Option<Vec<String>>,
}

/// The split files a rosbag2 folder lists in `metadata.yaml` (those present, and those
/// missing), else its `.mcap` files. A listed path must stay inside the folder: absolute
/// paths, `..` and links that lead out are refused.
fn folder_files(dir: &Path) -> Result<(Vec<PathBuf>, Vec<PathBuf>), BagError> {
    let metadata = dir.join("metadata.yaml");
    let bad = |reason: String| BagError::Metadata {
        path: metadata.clone(),
        reason,
    };
    let listed = if metadata.exists() {
        let bytes = crate::textfile::read_bounded(&metadata, crate::textfile::MAX_TEXT_BYTES)
            .map_err(|e| bad(format!("cannot read: {e}")))?;
        let text = String::from_utf8_lossy(&bytes);
        let parsed: Metadata = serde_saphyr::from_str(&text).map_err(|e| {
            bad(format!(
                "not rosbag2 metadata: {}",
                e.to_string().lines().next().unwrap_or("unreadable")
            ))
        })?;
        parsed
            .rosbag2_bagfile_information
            .and_then(|i| i.relative_file_paths)
            .filter(|v| !v.is_empty())
    } else {
        None
    };
    let Some(listed) = listed else {
        let files = mcap_files(dir);
        if files.is_empty() {
            return Err(BagError::NoMcap {
                path: dir.to_path_buf(),
            });
        }
        return Ok((files, Vec::new()));
    };
    let root = std::fs::canonicalize(dir).map_err(|source| BagError::Open {
        path: dir.to_path_buf(),
        source,
    })?;
    let (mut files, mut missing) = (Vec::new(), Vec::new());
    for name in &listed {
        let relative = Path::new(name);
        let leaves = relative.is_absolute()
            || relative.components().any(|c| {
                !matches!(
                    c,
                    std::path::Component::Normal(_) | std::path::Component::CurDir
                )
            });
        if leaves {
            return Err(bad(format!(
                "relative_file_paths: `{name}` is not a path inside the bag folder (refused)"
            )));
        }
        let path = dir.join(relative);
        match std::fs::canonicalize(&path) {
            Ok(real) if !real.starts_with(&root) => {
                return Err(bad(format!(
                    "relative_file_paths: `{name}` leads outside the bag folder, to {} (refused)",
                    real.display()
                )));
            }
            Ok(real) if real.is_file() => files.push(path),
            Ok(_) => {
                return Err(bad(format!("relative_file_paths: `{name}` is not a file")));
            }
            Err(_) => missing.push(path),
        }
    }
    if files.is_empty() {
        return Err(bad(format!(
            "none of the {} files it lists is there (missing: {})",
            missing.len(),
            names(&missing)
        )));
    }
    Ok((files, missing))
}

/// `a.mcap, b.mcap`: the file names of `paths`.
fn names(paths: &[PathBuf]) -> String {
    paths
        .iter()
        .map(|p| p.display().to_string())
        .collect::<Vec<_>>()
        .join(", ")
}

fn corrupt(source: McapError) -> BagError {
    BagError::Mcap {
        source,
        after: String::new(),
    }
}

impl Bag {
    /// Opens a bag file or folder and learns its topics.
    ///
    /// # Errors
    /// The path cannot be read, is not MCAP, or its summary is malformed.
    pub fn open(path: &Path) -> Result<Self, BagError> {
        let meta = std::fs::metadata(path).map_err(|source| BagError::Open {
            path: path.to_path_buf(),
            source,
        })?;
        let (files, missing) = if meta.is_dir() {
            folder_files(path)?
        } else {
            (vec![path.to_path_buf()], Vec::new())
        };
        let mut topics: BTreeMap<String, Topic> = BTreeMap::new();
        let mut scan_error: Option<McapError> = None;
        for file in &files {
            let mut reader = McapReader::open(file).map_err(corrupt)?;
            let mut add = |schemas: &BTreeMap<u16, mcap::Schema>,
                           channels: &BTreeMap<u16, mcap::Channel>,
                           counts: Option<&BTreeMap<u16, u64>>| {
                for c in channels.values() {
                    let type_name = schemas
                        .get(&c.schema_id)
                        .map_or_else(String::new, |s| s.name.clone());
                    let n = counts.map(|m| m.get(&c.id).copied().unwrap_or(0));
                    let t = topics.entry(c.topic.clone()).or_insert(Topic {
                        type_name,
                        encoding: c.message_encoding.clone(),
                        count: Some(0),
                    });
                    t.count = match (t.count, n) {
                        (Some(a), Some(b)) => Some(a + b),
                        _ => None,
                    };
                }
            };
            match reader.summary().map_err(corrupt)? {
                Some(s) if !s.channels.is_empty() => {
                    let counts = (!s.message_counts.is_empty()).then_some(&s.message_counts);
                    add(&s.schemas, &s.channels, counts);
                }
                _ => {
                    // No summary: scan the file for its channels and count the messages.
                    let mut counts: BTreeMap<u16, u64> = BTreeMap::new();
                    loop {
                        match reader.next_message() {
                            Ok(Some(m)) => *counts.entry(m.channel_id).or_default() += 1,
                            Ok(None) => break,
                            // A broken file: the topics seen so far are known; the stream
                            // reports the error where it happens. A file broken before
                            // any channel is kept to explain an empty bag.
                            Err(e) => {
                                if reader.channels().is_empty() && scan_error.is_none() {
                                    scan_error = Some(e);
                                }
                                break;
                            }
                        }
                    }
                    add(reader.schemas(), reader.channels(), Some(&counts));
                }
            }
        }
        // "no image topic; topics: none" said nothing of a bag cut before its first channel.
        if topics.is_empty()
            && let Some(e) = scan_error
        {
            return Err(corrupt(e));
        }
        Ok(Self {
            files,
            missing,
            topics,
        })
    }

    /// The split files `metadata.yaml` lists that are not in the folder (the others are
    /// read; `track` reports these and exits with code 3).
    pub fn missing_files(&self) -> &[PathBuf] {
        &self.missing
    }

    /// The bag's files, in order.
    pub fn files(&self) -> &[PathBuf] {
        &self.files
    }

    /// The bag's topics by name.
    pub fn topics(&self) -> &BTreeMap<String, Topic> {
        &self.topics
    }

    fn listing(&self, wanted: &[&str]) -> String {
        let list: Vec<String> = self
            .topics
            .iter()
            .filter(|(_, t)| wanted.is_empty() || wanted.contains(&t.type_name.as_str()))
            .map(|(name, t)| format!("{name} ({})", t.type_name))
            .collect();
        if list.is_empty() {
            "none".into()
        } else {
            list.join(", ")
        }
    }

    /// The image topic: `choice` if given (it must exist), else the bag's only topic of
    /// type `Image` or `CompressedImage`.
    ///
    /// # Errors
    /// No such topic, no image topic, or several (the message lists them).
    pub fn image_topic(&self, choice: Option<&str>) -> Result<String, BagError> {
        if let Some(topic) = choice {
            if self.topics.contains_key(topic) {
                return Ok(topic.to_owned());
            }
            return Err(BagError::Topic(format!(
                "--image-topic {topic}: no such topic in the bag (topics: {})",
                self.listing(&[])
            )));
        }
        let images: Vec<&String> = self
            .topics
            .iter()
            .filter(|(_, t)| t.type_name == IMAGE || t.type_name == COMPRESSED_IMAGE)
            .map(|(n, _)| n)
            .collect();
        match images.as_slice() {
            [one] => Ok((*one).clone()),
            [] => Err(BagError::Topic(format!(
                "the bag has no image topic ({IMAGE} or {COMPRESSED_IMAGE}); topics: {}",
                self.listing(&[])
            ))),
            _ => Err(BagError::Topic(format!(
                "the bag has several image topics, pick one with --image-topic: {}",
                self.listing(&[IMAGE, COMPRESSED_IMAGE])
            ))),
        }
    }

    /// The `CameraInfo` topic that goes with `image_topic`: the only one, else the one in
    /// the image topic's namespace (the longest match).
    ///
    /// # Errors
    /// No `CameraInfo` topic, or several and none in the image's namespace.
    pub fn camera_info_topic(&self, image_topic: &str) -> Result<String, BagError> {
        let infos: Vec<&String> = self
            .topics
            .iter()
            .filter(|(_, t)| t.type_name == CAMERA_INFO)
            .map(|(n, _)| n)
            .collect();
        if let [one] = infos.as_slice() {
            return Ok((*one).clone());
        }
        if infos.is_empty() {
            return Err(BagError::Topic(format!(
                "no --camera and the bag has no {CAMERA_INFO} topic to calibrate from: pass \
                 --camera FILE (topics: {})",
                self.listing(&[])
            )));
        }
        let namespace = |t: &str| t.rsplit_once('/').map_or("", |(ns, _)| ns).to_owned();
        let best = infos
            .iter()
            .filter(|t| {
                let ns = namespace(t);
                image_topic.starts_with(&format!("{ns}/"))
            })
            .max_by_key(|t| namespace(t).len());
        best.map(|t| (*t).clone()).ok_or_else(|| {
            BagError::Topic(format!(
                "several {CAMERA_INFO} topics and none in the namespace of {image_topic}: {}; \
                 pass --camera FILE",
                self.listing(&[CAMERA_INFO])
            ))
        })
    }

    /// The follower-inputs topic: `choice` if given, else the only `Odometry` topic, else
    /// the only `TwistStamped`, else the only `Twist`; `None` when the bag has none.
    ///
    /// # Errors
    /// No such topic, a topic of another type, or several of the first type found.
    pub fn inputs_topic(&self, choice: Option<&str>) -> Result<Option<String>, BagError> {
        if let Some(topic) = choice {
            return match self.topics.get(topic) {
                Some(t) if cdr::TWIST_TYPES.contains(&t.type_name.as_str()) => {
                    Ok(Some(topic.to_owned()))
                }
                Some(t) => Err(BagError::Topic(format!(
                    "--inputs-topic {topic} carries {}, not {}",
                    t.type_name,
                    cdr::TWIST_TYPES.join(", ")
                ))),
                None => Err(BagError::Topic(format!(
                    "--inputs-topic {topic}: no such topic in the bag (topics: {})",
                    self.listing(&[])
                ))),
            };
        }
        for kind in cdr::TWIST_TYPES {
            let found: Vec<&String> = self
                .topics
                .iter()
                .filter(|(_, t)| t.type_name == kind)
                .map(|(n, _)| n)
                .collect();
            match found.as_slice() {
                [] => continue,
                [one] => return Ok(Some((*one).clone())),
                _ => {
                    return Err(BagError::Topic(format!(
                        "several {kind} topics could give the follower's inputs, pick one with \
                         --inputs-topic: {}",
                        self.listing(&[kind])
                    )));
                }
            }
        }
        Ok(None)
    }

    /// The calibration from the first message on `topic` (a `CameraInfo` topic).
    ///
    /// # Errors
    /// The topic has no message, its first message is not a `CameraInfo` or gives no
    /// usable calibration (e.g. a zero focal length, an unsupported distortion model).
    pub fn calibration(&self, topic: &str) -> Result<pose::Camera, BagError> {
        let err = |reason: String| BagError::Message {
            topic: topic.to_owned(),
            index: 0,
            reason,
            fatal: true,
        };
        for file in &self.files {
            let mut reader = McapReader::open(file).map_err(corrupt)?;
            loop {
                let channel_id = match reader.next_message() {
                    Ok(Some(m)) => m.channel_id,
                    Ok(None) => break,
                    Err(e) => return Err(corrupt(e)),
                };
                let Some(channel) = reader.channels().get(&channel_id) else {
                    continue;
                };
                if channel.topic != topic {
                    continue;
                }
                let type_name = reader
                    .schemas()
                    .get(&channel.schema_id)
                    .map_or_else(String::new, |s| s.name.clone());
                if type_name != CAMERA_INFO {
                    return Err(err(format!("{type_name} is not {CAMERA_INFO}")));
                }
                if channel.message_encoding != "cdr" {
                    return Err(err(format!(
                        "message encoding `{}` is not supported (cdr only)",
                        channel.message_encoding
                    )));
                }
                let info = cdr::CameraInfo::parse(reader.last_message_data()).map_err(&err)?;
                return pixels::calibration(&info).map_err(&err);
            }
        }
        Err(BagError::Topic(format!(
            "no CameraInfo message on {topic} to calibrate from: pass --camera FILE"
        )))
    }

    /// Streams the frames of `image_topic`, with the follower's inputs from
    /// `inputs_topic`.
    pub fn frames(
        &self,
        image_topic: &str,
        inputs_topic: Option<&str>,
        max_side: usize,
    ) -> BagFrames {
        BagFrames {
            files: self.files.clone().into(),
            reader: None,
            roles: BTreeMap::new(),
            image_topic: image_topic.to_owned(),
            inputs_topic: inputs_topic.map(str::to_owned),
            max_side,
            pending: BinaryHeap::new(),
            pool: Vec::new(),
            current: GreyImage::default(),
            inputs: VecDeque::new(),
            held: None,
            next_seq: 0,
            max_seq: None,
            image_messages: 0,
            input_messages: 0,
            released: 0,
            last_stamp: None,
            period_ns: None,
            ended: false,
            stats: BagStats::default(),
            total: self.topics.get(image_topic).and_then(|t| t.count),
        }
    }
}

/// What the stream saw that was not a regular sequence of frames.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct BagStats {
    /// Image messages read on the image topic.
    pub messages: u64,
    /// Frames handed out, in `header.stamp` order.
    pub frames: u64,
    /// Frames that arrived out of `header.stamp` order and were put back in order by the
    /// reorder window.
    pub reordered: u64,
    /// Frames that arrived later than the window allows (or with a repeated stamp): not
    /// tracked, since the filter cannot go back in time.
    pub out_of_order_dropped: u64,
    /// Frames missing from the sequence: gaps between consecutive stamps of about `n`
    /// nominal periods count `n - 1`.
    pub dropped: u64,
    /// Intervals between frames that are not within 25 % of a whole number of nominal
    /// periods.
    pub irregular: u64,
    /// Input messages whose stamp was older than a frame already handed out when they
    /// arrived (not used).
    pub late_inputs: u64,
}

/// What a channel is to the stream.
#[derive(Debug, Clone)]
enum Role {
    Image {
        compressed: bool,
    },
    Inputs {
        type_name: String,
    },
    Other,
    /// The image or inputs topic with a type or encoding we cannot read: the message
    /// says why.
    Bad {
        topic: String,
        reason: String,
    },
}

/// A decoded frame waiting in the reorder window.
#[derive(Debug)]
struct Pending {
    stamp_ns: u64,
    seq: u64,
    message: u64,
    image: GreyImage,
}

impl PartialEq for Pending {
    fn eq(&self, other: &Self) -> bool {
        (self.stamp_ns, self.seq) == (other.stamp_ns, other.seq)
    }
}
impl Eq for Pending {}
impl PartialOrd for Pending {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Pending {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        (self.stamp_ns, self.seq).cmp(&(other.stamp_ns, other.seq))
    }
}

/// One frame of a bag.
#[derive(Debug, Clone, Copy)]
pub struct BagFrame<'a> {
    /// Frame number from 0, in stamp order.
    pub index: u64,
    /// The message's index on the image topic, from 0 (in file order).
    pub message: u64,
    /// `header.stamp`, nanoseconds.
    pub stamp_ns: u64,
    /// Frames missing just before this one: a gap of about `n` nominal periods counts
    /// `n - 1`.
    pub missing_before: u64,
    /// The nominal frame period, seconds (see [`BagFrames::nominal_period`]).
    pub period_s: Option<f64>,
    /// The follower's inputs `(v2, w2)` as of the stamp (the latest input message stamped at
    /// or before it); `None` before the first.
    pub inputs: Option<unicycle::Inputs>,
    /// The grey image.
    pub image: &'a GreyImage,
}

/// The frames of one image topic (see [`Bag::frames`]).
#[derive(Debug)]
pub struct BagFrames {
    files: VecDeque<PathBuf>,
    reader: Option<McapReader>,
    roles: BTreeMap<u16, Role>,
    image_topic: String,
    inputs_topic: Option<String>,
    max_side: usize,
    pending: BinaryHeap<Reverse<Pending>>,
    pool: Vec<GreyImage>,
    current: GreyImage,
    /// Input samples not yet used, in stamp order.
    inputs: VecDeque<(u64, unicycle::Inputs)>,
    /// The input in force (the latest used).
    held: Option<unicycle::Inputs>,
    next_seq: u64,
    max_seq: Option<u64>,
    image_messages: u64,
    input_messages: u64,
    released: u64,
    last_stamp: Option<u64>,
    period_ns: Option<u64>,
    ended: bool,
    stats: BagStats,
    total: Option<u64>,
}

impl BagFrames {
    /// Image messages on the topic, when the summaries say.
    pub fn len_hint(&self) -> Option<u64> {
        self.total
    }

    /// What was irregular so far.
    pub fn stats(&self) -> BagStats {
        self.stats
    }

    /// The nominal frame period, seconds: the median interval of the first frames (known
    /// once the first frame is handed out, if there are two).
    pub fn nominal_period(&self) -> Option<f64> {
        self.period_ns.map(|p| p as f64 * 1e-9)
    }

    fn role(&self, reader: &McapReader, channel_id: u16) -> Role {
        let Some(c) = reader.channels().get(&channel_id) else {
            return Role::Other;
        };
        let type_name = reader
            .schemas()
            .get(&c.schema_id)
            .map_or_else(String::new, |s| s.name.clone());
        let bad = |reason: String| Role::Bad {
            topic: c.topic.clone(),
            reason,
        };
        let is_image = c.topic == self.image_topic;
        let is_inputs = self.inputs_topic.as_deref() == Some(c.topic.as_str());
        if !is_image && !is_inputs {
            return Role::Other;
        }
        if c.message_encoding != "cdr" {
            return bad(format!(
                "message encoding `{}` is not supported (cdr only)",
                c.message_encoding
            ));
        }
        if is_image {
            return match type_name.as_str() {
                IMAGE => Role::Image { compressed: false },
                COMPRESSED_IMAGE => Role::Image { compressed: true },
                other => bad(format!(
                    "{other} is not an image ({IMAGE} or {COMPRESSED_IMAGE}); pick the image \
                     topic with --image-topic"
                )),
            };
        }
        if cdr::TWIST_TYPES.contains(&type_name.as_str()) {
            Role::Inputs { type_name }
        } else {
            bad(format!(
                "{type_name} carries no follower inputs ({})",
                cdr::TWIST_TYPES.join(", ")
            ))
        }
    }

    /// Reads messages until a frame can be handed out (the window is full or the bag has
    /// ended). Returns an error for a broken message or file.
    fn fill(&mut self) -> Result<(), BagError> {
        while !self.ended && self.pending.len() <= REORDER_WINDOW {
            if self.reader.is_none() {
                match self.files.pop_front() {
                    Some(f) => {
                        self.reader = Some(McapReader::open(&f).map_err(|e| self.broken(e))?);
                        self.roles.clear();
                    }
                    None => {
                        self.ended = true;
                        break;
                    }
                }
            }
            let Some(reader) = self.reader.as_mut() else {
                continue;
            };
            let (channel_id, log_time) = match reader.next_message() {
                Ok(Some(m)) => (m.channel_id, m.log_time),
                Ok(None) => {
                    self.reader = None;
                    continue;
                }
                Err(e) => {
                    self.ended = true;
                    return Err(self.broken(e));
                }
            };
            if !self.roles.contains_key(&channel_id)
                && let Some(reader) = self.reader.as_ref()
            {
                let role = self.role(reader, channel_id);
                self.roles.insert(channel_id, role);
            }
            let role = self.roles.get(&channel_id).cloned().unwrap_or(Role::Other);
            match role {
                Role::Other => {}
                Role::Bad { topic, reason } => {
                    let index = if topic == self.image_topic {
                        self.image_messages
                    } else {
                        self.input_messages
                    };
                    self.ended = true;
                    return Err(BagError::Message {
                        topic,
                        index,
                        reason,
                        fatal: true,
                    });
                }
                Role::Image { compressed } => {
                    let index = self.image_messages;
                    self.image_messages += 1;
                    self.stats.messages += 1;
                    self.image(compressed, index)?;
                }
                Role::Inputs { type_name } => {
                    let index = self.input_messages;
                    self.input_messages += 1;
                    self.input(&type_name, index, log_time)?;
                }
            }
        }
        Ok(())
    }

    fn broken(&self, source: McapError) -> BagError {
        let after = if self.image_messages > 0 {
            format!(
                " (after message {} of {})",
                self.image_messages - 1,
                self.image_topic
            )
        } else {
            String::new()
        };
        BagError::Mcap { source, after }
    }

    /// Decodes the current message (an image) into a pooled buffer and queues it.
    fn image(&mut self, compressed: bool, index: u64) -> Result<(), BagError> {
        let mut grey = self.pool.pop().unwrap_or_default();
        let reader = self.reader.as_ref();
        let data = reader.map_or(&[][..], McapReader::last_message_data);
        let max_side = self.max_side;
        let decoded = if compressed {
            cdr::CompressedImage::parse(data).and_then(|img| {
                pixels::compressed_to_grey(&img, &mut grey, max_side).map(|()| img.stamp_ns)
            })
        } else {
            cdr::Image::parse(data).and_then(|img| {
                if !pixels::supported(&img.encoding) {
                    return Err(format!(
                        "image encoding `{}` is not supported (supported: {})",
                        img.encoding,
                        pixels::ENCODINGS.join(", ")
                    ));
                }
                pixels::raw_to_grey(&img, &mut grey, max_side).map(|()| img.stamp_ns)
            })
        };
        match decoded {
            Ok(stamp_ns) => {
                let seq = self.next_seq;
                self.next_seq += 1;
                self.pending.push(Reverse(Pending {
                    stamp_ns,
                    seq,
                    message: index,
                    image: grey,
                }));
                Ok(())
            }
            Err(reason) => {
                self.pool.push(grey);
                // An encoding we do not read will not change on the next message.
                let fatal = reason.contains("is not supported");
                if fatal {
                    self.ended = true;
                }
                Err(BagError::Message {
                    topic: self.image_topic.clone(),
                    index,
                    reason,
                    fatal,
                })
            }
        }
    }

    fn input(&mut self, type_name: &str, index: u64, log_time: u64) -> Result<(), BagError> {
        let data = self
            .reader
            .as_ref()
            .map_or(&[][..], McapReader::last_message_data);
        let sample =
            cdr::TwistSample::parse(type_name, data).map_err(|reason| BagError::Message {
                topic: self.inputs_topic.clone().unwrap_or_default(),
                index,
                reason,
                fatal: false,
            })?;
        let stamp = sample.stamp_ns.unwrap_or(log_time);
        if self.last_stamp.is_some_and(|last| stamp < last) {
            self.stats.late_inputs += 1;
            return Ok(());
        }
        let at = self.inputs.partition_point(|(s, _)| *s <= stamp);
        self.inputs
            .insert(at, (stamp, unicycle::Inputs::new(sample.v, sample.w)));
        Ok(())
    }

    /// The next frame in stamp order; `Ok(None)` at the end.
    ///
    /// # Errors
    /// A message that cannot be used ([`BagError::Message`]; the stream goes on unless
    /// [`BagError::is_fatal`]) or a broken file (the stream ends; frames already queued
    /// are still handed out by the next calls).
    pub fn next_frame(&mut self) -> Result<Option<BagFrame<'_>>, BagError> {
        loop {
            self.fill()?;
            if self.period_ns.is_none() && (self.ended || self.pending.len() > REORDER_WINDOW) {
                self.period_ns = median_interval(&self.pending);
            }
            let Some(Reverse(next)) = self.pending.pop() else {
                return Ok(None);
            };
            if self.last_stamp.is_some_and(|last| next.stamp_ns <= last) {
                self.stats.out_of_order_dropped += 1;
                self.pool.push(next.image);
                continue;
            }
            if self.max_seq.is_some_and(|m| next.seq < m) {
                // A frame read after a later-stamped one, put back in order.
                self.stats.reordered += 1;
            }
            self.max_seq = Some(self.max_seq.map_or(next.seq, |m| m.max(next.seq)));
            let mut missing_before = 0;
            if let (Some(last), Some(period)) = (self.last_stamp, self.period_ns) {
                let ratio = (next.stamp_ns - last) as f64 / period as f64;
                let whole = ratio.round().max(1.0);
                if (ratio - whole).abs() > 0.25 {
                    self.stats.irregular += 1;
                }
                missing_before = whole as u64 - 1;
                self.stats.dropped += missing_before;
            }
            self.last_stamp = Some(next.stamp_ns);
            while let Some((s, u)) = self.inputs.front().copied() {
                if s > next.stamp_ns {
                    break;
                }
                self.held = Some(u);
                self.inputs.pop_front();
            }
            let old = std::mem::replace(&mut self.current, next.image);
            self.pool.push(old);
            let index = self.released;
            self.released += 1;
            self.stats.frames += 1;
            return Ok(Some(BagFrame {
                index,
                message: next.message,
                stamp_ns: next.stamp_ns,
                missing_before,
                period_s: self.nominal_period(),
                inputs: self.held,
                image: &self.current,
            }));
        }
    }
}

/// The median of the positive intervals between the stamps in the window.
fn median_interval(pending: &BinaryHeap<Reverse<Pending>>) -> Option<u64> {
    let mut stamps: Vec<u64> = pending.iter().map(|Reverse(p)| p.stamp_ns).collect();
    stamps.sort_unstable();
    let mut gaps: Vec<u64> = stamps
        .windows(2)
        .map(|w| w[1] - w[0])
        .filter(|g| *g > 0)
        .collect();
    gaps.sort_unstable();
    gaps.get(gaps.len() / 2).copied()
}
