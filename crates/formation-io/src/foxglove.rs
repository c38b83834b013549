//! Tracking results as a Foxglove-ready MCAP file (`track --mcap`, the demo's `demo.mcap`).
//!
//! Channels (`docs/outputs.md` documents every field):
//!
//! | topic | schema | encoding |
//! |---|---|---|
//! | `/camera/image` | `sensor_msgs/msg/Image` (`ros2msg`), the grey frame as tracked, `mono8` | `cdr` |
//! | `/camera/annotations` | `foxglove.ImageAnnotations` (`jsonschema`) | `json` |
//! | `/tf` | `foxglove.FrameTransforms` (`jsonschema`) | `json` |
//! | `/formation/estimate` | `formation_tracker.FormationEstimate` (`jsonschema`) | `json` |
//!
//! The image is a ROS 2 `Image` in CDR (not a JSON `foxglove.RawImage`, whose pixels would be
//! base64 text a third larger): Foxglove's Image panel draws `ImageAnnotations` over it when
//! their timestamps match, which they do (both are the frame's stamp). Annotation points
//! use Foxglove's convention, the origin at the top-left corner of the top-left pixel: our
//! pixel centres (spec 2.1) are shifted by half a pixel.

use std::io::Write;

use formation_tracker::pipeline::PipelineFrame;
use formation_tracker::rig::RigModel;
use formation_tracker::robots::MarkerObservation;
use nalgebra::{Point2, Point3, Rotation3, UnitQuaternion, Vector3};
use pose::Camera;
use serde_json::{Value, json};

use crate::bag::cdr;
use crate::mcap_out::McapWriter;

/// The camera's frame id in `/tf` and on the images.
pub const CAMERA_FRAME: &str = "camera";

const SCHEMA_TIME: &str = r#"{"type":"object","properties":{"sec":{"type":"integer","minimum":0},"nsec":{"type":"integer","minimum":0,"maximum":999999999}}}"#;
const SCHEMA_COLOR: &str = r#"{"type":"object","properties":{"r":{"type":"number"},"g":{"type":"number"},"b":{"type":"number"},"a":{"type":"number"}}}"#;
const SCHEMA_POINT2: &str =
    r#"{"type":"object","properties":{"x":{"type":"number"},"y":{"type":"number"}}}"#;

fn annotations_schema() -> String {
    format!(
        r#"{{"title":"foxglove.ImageAnnotations","description":"Array of annotations for a 2D image","type":"object","properties":{{"circles":{{"type":"array","items":{{"type":"object","properties":{{"timestamp":{t},"position":{p},"diameter":{{"type":"number"}},"thickness":{{"type":"number"}},"fill_color":{c},"outline_color":{c}}}}}}},"points":{{"type":"array","items":{{"type":"object","properties":{{"timestamp":{t},"type":{{"type":"integer","enum":[0,1,2,3,4]}},"points":{{"type":"array","items":{p}}},"outline_color":{c},"outline_colors":{{"type":"array","items":{c}}},"fill_color":{c},"thickness":{{"type":"number"}}}}}}}},"texts":{{"type":"array","items":{{"type":"object","properties":{{"timestamp":{t},"position":{p},"text":{{"type":"string"}},"font_size":{{"type":"number"}},"text_color":{c},"background_color":{c}}}}}}}}}}}"#,
        t = SCHEMA_TIME,
        p = SCHEMA_POINT2,
        c = SCHEMA_COLOR
    )
}

fn transforms_schema() -> String {
    format!(
        r#"{{"title":"foxglove.FrameTransforms","description":"An array of FrameTransform messages","type":"object","properties":{{"transforms":{{"type":"array","items":{{"type":"object","properties":{{"timestamp":{t},"parent_frame_id":{{"type":"string"}},"child_frame_id":{{"type":"string"}},"translation":{{"type":"object","properties":{{"x":{{"type":"number"}},"y":{{"type":"number"}},"z":{{"type":"number"}}}}}},"rotation":{{"type":"object","properties":{{"x":{{"type":"number"}},"y":{{"type":"number"}},"z":{{"type":"number"}},"w":{{"type":"number"}}}}}}}}}}}}}}}}"#,
        t = SCHEMA_TIME
    )
}

fn estimate_schema() -> String {
    let num = r#"{"type":"number"}"#;
    format!(
        r#"{{"title":"formation_tracker.FormationEstimate","description":"The formation estimate of every tracked leader at one frame (docs/outputs.md)","type":"object","properties":{{"timestamp":{t},"frame":{{"type":"integer"}},"t":{num},"leaders":{{"type":"array","items":{{"type":"object","properties":{{"robot":{{"type":"integer"}},"status":{{"type":"string","enum":["tracking","coasting","lost"]}},"l12":{num},"alpha12":{num},"beta12":{num},"v1":{num},"w1":{num},"std":{{"type":"array","items":{num},"minItems":5,"maxItems":5}},"covariance":{{"type":"array","items":{num},"minItems":25,"maxItems":25}},"since_seen":{num}}}}}}}}}}}"#,
        t = SCHEMA_TIME
    )
}

/// `sensor_msgs/msg/Image` in the `ros2msg` schema language (with its dependencies).
const IMAGE_MSG: &str = "std_msgs/Header header\nuint32 height\nuint32 width\nstring encoding\nuint8 is_bigendian\nuint32 step\nuint8[] data\n================================================================================\nMSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n================================================================================\nMSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n";

/// The topics, as written.
pub const TOPIC_IMAGE: &str = "/camera/image";
/// Marker outlines, labels and reprojected rigs.
pub const TOPIC_ANNOTATIONS: &str = "/camera/annotations";
/// Camera to each leader.
pub const TOPIC_TF: &str = "/tf";
/// The formation estimate per leader.
pub const TOPIC_ESTIMATE: &str = "/formation/estimate";

/// One frame's inputs to the writer.
#[derive(Debug, Clone, Copy)]
pub struct FrameOut<'a> {
    /// Frame number.
    pub frame: u64,
    /// Time of the frame, nanoseconds (the stamp of every message of the frame).
    pub stamp_ns: u64,
    /// Seconds since the first frame (the tracker's `t`).
    pub t: f64,
    /// The grey image (`width * height` bytes), or `None` to leave it out.
    pub image: Option<(&'a [u8], usize, usize)>,
    /// What the pipeline made of it.
    pub result: &'a PipelineFrame,
    /// The markers it read.
    pub markers: &'a [MarkerObservation],
}

/// Writes tracking results as MCAP.
#[derive(Debug)]
pub struct FoxgloveWriter<W: Write> {
    mcap: McapWriter<W>,
    rig: RigModel,
    calibration: Camera,
    image: Option<u16>,
    annotations: u16,
    tf: u16,
    estimate: u16,
}

fn colour(robot: u32) -> Value {
    const PALETTE: [[f64; 3]; 6] = [
        [0.95, 0.26, 0.21],
        [0.13, 0.59, 0.95],
        [0.30, 0.69, 0.31],
        [1.0, 0.60, 0.0],
        [0.61, 0.15, 0.69],
        [0.0, 0.74, 0.83],
    ];
    let c = PALETTE[robot as usize % PALETTE.len()];
    json!({"r": c[0], "g": c[1], "b": c[2], "a": 1.0})
}

fn time(stamp_ns: u64) -> Value {
    json!({"sec": stamp_ns / 1_000_000_000, "nsec": stamp_ns % 1_000_000_000})
}

/// Our pixel (centre convention) as a Foxglove image point.
fn point(p: Point2<f64>) -> Value {
    json!({"x": p.x + 0.5, "y": p.y + 0.5})
}

impl<W: Write> FoxgloveWriter<W> {
    /// A writer over `out`; `images`: whether the frames go in too.
    ///
    /// # Errors
    /// A failed write.
    pub fn new(out: W, rig: RigModel, calibration: Camera, images: bool) -> std::io::Result<Self> {
        let mut mcap = McapWriter::new(out, "")?;
        let image = if images {
            let s = mcap.add_schema("sensor_msgs/msg/Image", "ros2msg", IMAGE_MSG.as_bytes())?;
            Some(mcap.add_channel(s, TOPIC_IMAGE, "cdr")?)
        } else {
            None
        };
        let s = mcap.add_schema(
            "foxglove.ImageAnnotations",
            "jsonschema",
            annotations_schema().as_bytes(),
        )?;
        let annotations = mcap.add_channel(s, TOPIC_ANNOTATIONS, "json")?;
        let s = mcap.add_schema(
            "foxglove.FrameTransforms",
            "jsonschema",
            transforms_schema().as_bytes(),
        )?;
        let tf = mcap.add_channel(s, TOPIC_TF, "json")?;
        let s = mcap.add_schema(
            "formation_tracker.FormationEstimate",
            "jsonschema",
            estimate_schema().as_bytes(),
        )?;
        let estimate = mcap.add_channel(s, TOPIC_ESTIMATE, "json")?;
        Ok(Self {
            mcap,
            rig,
            calibration,
            image,
            annotations,
            tf,
            estimate,
        })
    }

    /// Projects a camera-frame point through the calibration (with its distortion).
    fn project(&self, p: &Point3<f64>) -> Option<Point2<f64>> {
        self.calibration.project(p).ok()
    }

    /// Writes one frame's messages.
    ///
    /// # Errors
    /// A failed write.
    pub fn frame(&mut self, f: &FrameOut<'_>) -> std::io::Result<()> {
        let stamp = f.stamp_ns;
        if let (Some(channel), Some((data, w, h))) = (self.image, f.image) {
            let msg = cdr::mono8_image(stamp, CAMERA_FRAME, w as u32, h as u32, data);
            self.mcap.write(channel, stamp, &msg)?;
        }
        let ts = time(stamp);
        let mut outlines = Vec::new();
        let mut texts = Vec::new();
        for m in f.markers {
            let label = self.rig.robot_face(m.index).map_or_else(
                || format!("id {}", m.index),
                |(robot, face)| format!("robot {robot} face {face}"),
            );
            let c = self
                .rig
                .robot_face(m.index)
                .map_or_else(|| colour(99), |(r, _)| colour(r));
            outlines.push(json!({
                "timestamp": ts, "type": 2, "thickness": 2.0,
                "points": m.corners.iter().map(|p| point(*p)).collect::<Vec<_>>(),
                "outline_color": c, "outline_colors": [],
                "fill_color": {"r": 0.0, "g": 0.0, "b": 0.0, "a": 0.0},
            }));
            texts.push(json!({
                "timestamp": ts, "position": point(m.corners[0]), "text": label,
                "font_size": 14.0, "text_color": c,
                "background_color": {"r": 0.0, "g": 0.0, "b": 0.0, "a": 0.6},
            }));
        }
        let mut transforms = Vec::new();
        let faces = self.rig.face_geometries().unwrap_or_default();
        for r in &f.result.robots {
            let rot = Rotation3::new(Vector3::from(r.rotation));
            let t = Vector3::from(r.translation);
            for face in &faces {
                let pts: Option<Vec<Value>> = face
                    .corner_points()
                    .iter()
                    .map(|p| self.project(&Point3::from(rot * p.coords + t)).map(point))
                    .collect();
                if let Some(pts) = pts {
                    outlines.push(json!({
                        "timestamp": ts, "type": 2, "thickness": 1.0, "points": pts,
                        "outline_color": {"r": 1.0, "g": 1.0, "b": 0.0, "a": 0.9},
                        "outline_colors": [],
                        "fill_color": {"r": 0.0, "g": 0.0, "b": 0.0, "a": 0.0},
                    }));
                }
            }
            let q = UnitQuaternion::from_rotation_matrix(&rot);
            transforms.push(json!({
                "timestamp": ts, "parent_frame_id": CAMERA_FRAME,
                "child_frame_id": format!("robot_{}", r.robot),
                "translation": {"x": t.x, "y": t.y, "z": t.z},
                "rotation": {"x": q.i, "y": q.j, "z": q.k, "w": q.w},
            }));
        }
        let annotations = json!({"circles": [], "points": outlines, "texts": texts});
        self.mcap.write(
            self.annotations,
            stamp,
            serde_json::to_string(&annotations)?.as_bytes(),
        )?;
        let tf = json!({ "transforms": transforms });
        self.mcap
            .write(self.tf, stamp, serde_json::to_string(&tf)?.as_bytes())?;
        let leaders: Vec<Value> = f
            .result
            .report
            .leaders
            .iter()
            .map(|l| {
                let std = [l.l12_std, l.alpha12_std, l.beta12_std, l.v1_std, l.w1_std];
                let cov: Vec<f64> = l.covariance.iter().flatten().copied().collect();
                json!({
                    "robot": l.robot,
                    "status": format!("{:?}", l.status).to_lowercase(),
                    "l12": l.formation.l12, "alpha12": l.formation.alpha12, "beta12": l.formation.beta12,
                    "v1": l.v1, "w1": l.w1, "std": std, "covariance": cov,
                    "since_seen": l.since_seen,
                })
            })
            .collect();
        let estimate = json!({"timestamp": ts, "frame": f.frame, "t": f.t, "leaders": leaders});
        self.mcap.write(
            self.estimate,
            stamp,
            serde_json::to_string(&estimate)?.as_bytes(),
        )?;
        Ok(())
    }

    /// Ends the file.
    ///
    /// # Errors
    /// A failed write.
    pub fn finish(self) -> std::io::Result<W> {
        self.mcap.finish()
    }
}
