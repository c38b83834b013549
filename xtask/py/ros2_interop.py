"""The other side of `cargo xtask ros2-interop`: CycloneDDS (the DDS behind ROS 2's
rmw_cyclonedds), through its Python binding, talks to `formation-tracker ros2`.

Run by xtask inside a private network namespace, with the node already started. It
defines the ROS 2 message types itself, from the standard .msg definitions, as plain
final structs under their DDS names (`sensor_msgs::msg::dds_::Image_`, ...), which is what
rmw_cyclonedds does, and encodes them as XCDR1 (the encoding ROS 2 uses). Then it

1. subscribes to every topic the node publishes (each leader's pose, pose_base, twist and
   formation topics for the leader ids in the manifest, formation/annotations, /tf,
   /diagnostics, and ROS 2's parameter_events and ros_discovery_info), reliable, keeping
   every sample;
2. publishes the recording as a camera driver would: per frame a mono8 Image, its
   CameraInfo and the follower's Odometry on rt/image_raw, rt/camera_info and rt/odom,
   stamped k/fps seconds after a whole second, at fps, once the node's readers matched,
   until the node exits (--max-frames) or the recording ends;
3. decodes every sample received (CDR little endian, XCDR1) and checks that the decoded
   sample encodes back to the same bytes, so that every byte was read by our definition;
4. compares with the node's own JSON lines: every formation array equals the robot,
   status, since_seen, l12_std, estimate and covariance of the same frame (matched by
   stamp) to 1e-12, the twists carry the same v1 and w1, the poses are in `camera` and
   `base_link` with a symmetric covariance and a unit quaternion, /tf and the annotations
   match the frame's leaders and markers, and every message the node published (one per
   leader per frame, one annotations message per frame, one /tf message per frame with a
   leader) arrived. Two losses are the node's and are tolerated unless the manifest says
   `strict` (see `account` in `check`);
5. compares the node's lines, the node being fed by CycloneDDS, with `track` on the same
   files (the estimates and covariances to 1e-12): the node read the pixels, the
   calibration and the odometry exactly;
6. checks that every topic the node publishes (seen through DDS discovery) is one it
   reads, under the same type name (the node's parameter service replies aside), and that
   ros_discovery_info lists the node with all its writers (what `ros2 node info` reads).

Prints a table per topic and writes a JSON summary (the manifest's `summary`); exits 1
with one line saying what failed. Usage: ros2_interop.py MANIFEST.json NODE_PID (the
node's process, watched to know when it has exited).
"""

import json
import math
import os
import sys
import time
import traceback
from dataclasses import dataclass, field

from cyclonedds.builtin import BuiltinDataReader, BuiltinTopicDcpsPublication
from cyclonedds.core import InstanceState, Policy, Qos, SampleState, ViewState
from cyclonedds.domain import DomainParticipant
from cyclonedds.idl import IdlStruct
from cyclonedds.idl.annotations import final
from cyclonedds.idl.types import array, float64, int32, int64, sequence, uint8, uint32
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from cyclonedds.util import duration

# The call DataReader.take makes, to get each sample's serialized bytes as well: a sample
# that fails to decode is then counted, not an exception that loses the others.
from cyclonedds._clayer import ddspy_take


def ros(pkg, name):
    """The DDS type name rmw_cyclonedds gives `pkg/msg/name`."""
    return f"{pkg}::msg::dds_::{name}_"


# --- The message types, field by field as in the .msg files ----------------------------

@final
@dataclass
class Time(IdlStruct, typename=ros("builtin_interfaces", "Time")):
    sec: int32 = 0
    nanosec: uint32 = 0


@final
@dataclass
class Header(IdlStruct, typename=ros("std_msgs", "Header")):
    stamp: Time = field(default_factory=Time)
    frame_id: str = ""


@final
@dataclass
class Image(IdlStruct, typename=ros("sensor_msgs", "Image")):
    header: Header = field(default_factory=Header)
    height: uint32 = 0
    width: uint32 = 0
    encoding: str = ""
    is_bigendian: uint8 = 0
    step: uint32 = 0
    data: sequence[uint8] = field(default_factory=list)


@final
@dataclass
class RegionOfInterest(IdlStruct, typename=ros("sensor_msgs", "RegionOfInterest")):
    x_offset: uint32 = 0
    y_offset: uint32 = 0
    height: uint32 = 0
    width: uint32 = 0
    do_rectify: bool = False


@final
@dataclass
class CameraInfo(IdlStruct, typename=ros("sensor_msgs", "CameraInfo")):
    header: Header = field(default_factory=Header)
    height: uint32 = 0
    width: uint32 = 0
    distortion_model: str = ""
    d: sequence[float64] = field(default_factory=list)
    k: array[float64, 9] = field(default_factory=lambda: [0.0] * 9)
    r: array[float64, 9] = field(default_factory=lambda: [0.0] * 9)
    p: array[float64, 12] = field(default_factory=lambda: [0.0] * 12)
    binning_x: uint32 = 0
    binning_y: uint32 = 0
    roi: RegionOfInterest = field(default_factory=RegionOfInterest)


@final
@dataclass
class Vector3(IdlStruct, typename=ros("geometry_msgs", "Vector3")):
    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0


@final
@dataclass
class Point(IdlStruct, typename=ros("geometry_msgs", "Point")):
    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0


@final
@dataclass
class Quaternion(IdlStruct, typename=ros("geometry_msgs", "Quaternion")):
    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0
    w: float64 = 1.0


@final
@dataclass
class Pose(IdlStruct, typename=ros("geometry_msgs", "Pose")):
    position: Point = field(default_factory=Point)
    orientation: Quaternion = field(default_factory=Quaternion)


@final
@dataclass
class PoseWithCovariance(IdlStruct, typename=ros("geometry_msgs", "PoseWithCovariance")):
    pose: Pose = field(default_factory=Pose)
    covariance: array[float64, 36] = field(default_factory=lambda: [0.0] * 36)


@final
@dataclass
class PoseWithCovarianceStamped(
    IdlStruct, typename=ros("geometry_msgs", "PoseWithCovarianceStamped")
):
    header: Header = field(default_factory=Header)
    pose: PoseWithCovariance = field(default_factory=PoseWithCovariance)


@final
@dataclass
class Twist(IdlStruct, typename=ros("geometry_msgs", "Twist")):
    linear: Vector3 = field(default_factory=Vector3)
    angular: Vector3 = field(default_factory=Vector3)


@final
@dataclass
class TwistWithCovariance(IdlStruct, typename=ros("geometry_msgs", "TwistWithCovariance")):
    twist: Twist = field(default_factory=Twist)
    covariance: array[float64, 36] = field(default_factory=lambda: [0.0] * 36)


@final
@dataclass
class TwistWithCovarianceStamped(
    IdlStruct, typename=ros("geometry_msgs", "TwistWithCovarianceStamped")
):
    header: Header = field(default_factory=Header)
    twist: TwistWithCovariance = field(default_factory=TwistWithCovariance)


@final
@dataclass
class Odometry(IdlStruct, typename=ros("nav_msgs", "Odometry")):
    header: Header = field(default_factory=Header)
    child_frame_id: str = ""
    pose: PoseWithCovariance = field(default_factory=PoseWithCovariance)
    twist: TwistWithCovariance = field(default_factory=TwistWithCovariance)


@final
@dataclass
class Transform(IdlStruct, typename=ros("geometry_msgs", "Transform")):
    translation: Vector3 = field(default_factory=Vector3)
    rotation: Quaternion = field(default_factory=Quaternion)


@final
@dataclass
class TransformStamped(IdlStruct, typename=ros("geometry_msgs", "TransformStamped")):
    header: Header = field(default_factory=Header)
    child_frame_id: str = ""
    transform: Transform = field(default_factory=Transform)


@final
@dataclass
class TFMessage(IdlStruct, typename=ros("tf2_msgs", "TFMessage")):
    transforms: sequence[TransformStamped] = field(default_factory=list)


@final
@dataclass
class MultiArrayDimension(IdlStruct, typename=ros("std_msgs", "MultiArrayDimension")):
    label: str = ""
    size: uint32 = 0
    stride: uint32 = 0


@final
@dataclass
class MultiArrayLayout(IdlStruct, typename=ros("std_msgs", "MultiArrayLayout")):
    dim: sequence[MultiArrayDimension] = field(default_factory=list)
    data_offset: uint32 = 0


@final
@dataclass
class Float64MultiArray(IdlStruct, typename=ros("std_msgs", "Float64MultiArray")):
    layout: MultiArrayLayout = field(default_factory=MultiArrayLayout)
    data: sequence[float64] = field(default_factory=list)


@final
@dataclass
class KeyValue(IdlStruct, typename=ros("diagnostic_msgs", "KeyValue")):
    key: str = ""
    value: str = ""


@final
@dataclass
class DiagnosticStatus(IdlStruct, typename=ros("diagnostic_msgs", "DiagnosticStatus")):
    level: uint8 = 0  # `byte` in the .msg: an octet
    name: str = ""
    message: str = ""
    hardware_id: str = ""
    values: sequence[KeyValue] = field(default_factory=list)


@final
@dataclass
class DiagnosticArray(IdlStruct, typename=ros("diagnostic_msgs", "DiagnosticArray")):
    header: Header = field(default_factory=Header)
    status: sequence[DiagnosticStatus] = field(default_factory=list)


@final
@dataclass
class Color(IdlStruct, typename=ros("foxglove_msgs", "Color")):
    r: float64 = 0.0
    g: float64 = 0.0
    b: float64 = 0.0
    a: float64 = 0.0


@final
@dataclass
class Point2(IdlStruct, typename=ros("foxglove_msgs", "Point2")):
    x: float64 = 0.0
    y: float64 = 0.0


@final
@dataclass
class CircleAnnotation(IdlStruct, typename=ros("foxglove_msgs", "CircleAnnotation")):
    timestamp: Time = field(default_factory=Time)
    position: Point2 = field(default_factory=Point2)
    diameter: float64 = 0.0
    thickness: float64 = 0.0
    fill_color: Color = field(default_factory=Color)
    outline_color: Color = field(default_factory=Color)


@final
@dataclass
class PointsAnnotation(IdlStruct, typename=ros("foxglove_msgs", "PointsAnnotation")):
    timestamp: Time = field(default_factory=Time)
    type: uint8 = 0
    points: sequence[Point2] = field(default_factory=list)
    outline_color: Color = field(default_factory=Color)
    outline_colors: sequence[Color] = field(default_factory=list)
    fill_color: Color = field(default_factory=Color)
    thickness: float64 = 0.0


@final
@dataclass
class TextAnnotation(IdlStruct, typename=ros("foxglove_msgs", "TextAnnotation")):
    timestamp: Time = field(default_factory=Time)
    position: Point2 = field(default_factory=Point2)
    text: str = ""
    font_size: float64 = 0.0
    text_color: Color = field(default_factory=Color)
    background_color: Color = field(default_factory=Color)


@final
@dataclass
class ImageAnnotations(IdlStruct, typename=ros("foxglove_msgs", "ImageAnnotations")):
    circles: sequence[CircleAnnotation] = field(default_factory=list)
    points: sequence[PointsAnnotation] = field(default_factory=list)
    texts: sequence[TextAnnotation] = field(default_factory=list)


# ROS 2's own graph topics, which every node publishes (Jazzy's definitions).

@final
@dataclass
class Gid(IdlStruct, typename="rmw_dds_common::msg::dds_::Gid_"):
    data: array[uint8, 16] = field(default_factory=lambda: bytearray(16))


@final
@dataclass
class NodeEntitiesInfo(IdlStruct, typename="rmw_dds_common::msg::dds_::NodeEntitiesInfo_"):
    node_namespace: str = ""
    node_name: str = ""
    reader_gid_seq: sequence[Gid] = field(default_factory=list)
    writer_gid_seq: sequence[Gid] = field(default_factory=list)


@final
@dataclass
class ParticipantEntitiesInfo(
    IdlStruct, typename="rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_"
):
    gid: Gid = field(default_factory=Gid)
    node_entities_info_seq: sequence[NodeEntitiesInfo] = field(default_factory=list)


@final
@dataclass
class ParameterValue(IdlStruct, typename=ros("rcl_interfaces", "ParameterValue")):
    type: uint8 = 0
    bool_value: bool = False
    integer_value: int64 = 0
    double_value: float64 = 0.0
    string_value: str = ""
    byte_array_value: sequence[uint8] = field(default_factory=list)
    bool_array_value: sequence[bool] = field(default_factory=list)
    integer_array_value: sequence[int64] = field(default_factory=list)
    double_array_value: sequence[float64] = field(default_factory=list)
    string_array_value: sequence[str] = field(default_factory=list)


@final
@dataclass
class Parameter(IdlStruct, typename=ros("rcl_interfaces", "Parameter")):
    name: str = ""
    value: ParameterValue = field(default_factory=ParameterValue)


@final
@dataclass
class ParameterEvent(IdlStruct, typename=ros("rcl_interfaces", "ParameterEvent")):
    stamp: Time = field(default_factory=Time)
    node: str = ""
    new_parameters: sequence[Parameter] = field(default_factory=list)
    changed_parameters: sequence[Parameter] = field(default_factory=list)
    deleted_parameters: sequence[Parameter] = field(default_factory=list)


# --- Helpers -------------------------------------------------------------------------

class Failure(Exception):
    """A check failed: the message is the one line printed."""


def stamp_ns_of(t):
    if t.sec < 0 or t.nanosec >= 1_000_000_000:
        raise Failure(f"stamp {t.sec}.{t.nanosec:09d} is not a time")
    return t.sec * 1_000_000_000 + t.nanosec


def qos_reader(durable=False):
    # Reliable and keeping every sample: a message the node publishes is either received
    # or a failure, never silently overwritten. ROS 2's graph topics are transient local
    # (keep last 1): `durable` reads the sample written before we joined.
    return Qos(
        Policy.Reliability.Reliable(max_blocking_time=duration(seconds=1)),
        Policy.Durability.TransientLocal if durable else Policy.Durability.Volatile,
        Policy.History.KeepAll,
        Policy.DataRepresentation(use_cdrv0_representation=True),
    )


def qos_writer(depth):
    # A camera driver's writer: reliable keep-last (it still serves the node's best-effort
    # readers); XCDR1, as rmw_cyclonedds writes.
    return Qos(
        Policy.Reliability.Reliable(max_blocking_time=duration(seconds=1)),
        Policy.Durability.Volatile,
        Policy.History.KeepLast(depth),
        Policy.DataRepresentation(use_cdrv0_representation=True),
    )


class Stream:
    """One topic the node publishes: our reader and what came out of it."""

    def __init__(self, dp, name, kind, dds_topic=None, durable=False):
        self.name = name
        self.kind = kind
        self.dds_topic = dds_topic or "rt/" + name
        self.label = "/" + name if dds_topic is None else f"{dds_topic} (DDS)"
        self.topic = Topic(dp, self.dds_topic, kind)
        self.reader = DataReader(dp, self.topic, qos=qos_reader(durable))
        self.samples = []
        self.received = 0
        self.failures = []
        self.encodings = set()

    def poll(self):
        mask = SampleState.Any | ViewState.Any | InstanceState.Any
        while True:
            got = ddspy_take(self.reader._ref, mask, 64)
            if isinstance(got, int):
                raise Failure(f"{self.name}: take failed ({got})")
            if not got:
                return
            for data, info in got:
                if not info.valid_data:
                    continue
                self.received += 1
                raw = bytes(data)
                self.encodings.add(raw[:2].hex())
                try:
                    msg = self.kind.deserialize(raw)
                except Exception as e:  # noqa: BLE001 - any decode error is a failure
                    self.failures.append(f"cannot decode ({e!r}); {len(raw)} bytes")
                    continue
                # Every byte read: the decoded message encodes back to the payload, up to
                # the final alignment padding (RTPS pads to 4 bytes).
                again = msg.serialize(use_version_2=False)
                body, back = raw[4:], again[4:]
                if raw[:2] != b"\x00\x01":
                    self.failures.append(f"encapsulation {raw[:2].hex()} is not CDR_LE")
                elif not (body.startswith(back) and len(body) - len(back) < 4
                          and not any(body[len(back):])):
                    self.failures.append(
                        f"decoded {len(back)} of {len(body)} bytes or re-encoded differently"
                    )
                else:
                    self.samples.append(msg)


def wait_until(what, cond, timeout, node_alive):
    deadline = time.monotonic() + timeout
    while not cond():
        if not node_alive():
            raise Failure(f"the node exited while waiting for {what}")
        if time.monotonic() > deadline:
            raise Failure(f"timed out after {timeout} s waiting for {what}")
        time.sleep(0.02)


def process_alive(pid):
    try:
        with open(f"/proc/{pid}/stat") as f:
            state = f.read().rsplit(")", 1)[1].split()[0]
        return state not in ("Z", "X")
    except (FileNotFoundError, ProcessLookupError, IndexError):
        return False


# --- The run ---------------------------------------------------------------------------

def main():
    if len(sys.argv) != 3:
        print(__doc__, file=sys.stderr)
        return 2
    with open(sys.argv[1]) as f:
        manifest = json.load(f)
    manifest["node_pid"] = int(sys.argv[2])
    try:
        summary = run(manifest)
    except Failure as e:
        print(f"ros2-interop: FAILED: {e}", flush=True)
        return 1
    except Exception as e:  # noqa: BLE001 - a bug here still ends with one line
        traceback.print_exc()
        print(f"ros2-interop: FAILED: the script stopped: {e!r}", flush=True)
        return 1
    with open(manifest["summary"], "w") as f:
        json.dump(summary, f, indent=1)
    return 0


def run(m):
    fps = float(m["fps"])
    node_pid = int(m["node_pid"])
    alive = lambda: process_alive(node_pid)  # noqa: E731
    dp = DomainParticipant(int(os.environ.get("ROS_DOMAIN_ID", "0")))

    # 1. Readers first, for every topic the node can publish: the leaders' publishers are
    # made when a leader first appears, and find our readers already there.
    streams = {}
    for n in m["leader_ids"]:
        base = f"formation/leader_{n}"
        streams[f"{base}/pose"] = PoseWithCovarianceStamped
        streams[f"{base}/pose_base"] = PoseWithCovarianceStamped
        streams[f"{base}/twist"] = TwistWithCovarianceStamped
        streams[f"{base}/formation"] = Float64MultiArray
    streams["formation/annotations"] = ImageAnnotations
    streams["tf"] = TFMessage
    streams["diagnostics"] = DiagnosticArray
    streams = {name: Stream(dp, name, kind) for name, kind in streams.items()}
    # ROS 2's graph: the node's parameter events, and which DDS entities are the node's
    # (what `ros2 node info` and `ros2 topic info` read).
    streams["parameter_events"] = Stream(dp, "parameter_events", ParameterEvent, durable=True)
    streams["ros_discovery_info"] = Stream(
        dp, "ros_discovery_info", ParticipantEntitiesInfo, "ros_discovery_info", durable=True
    )
    publications = BuiltinDataReader(dp, BuiltinTopicDcpsPublication)
    seen_topics = {}  # DDS topic -> type name, of every writer not ours
    seen_writers = {}  # writer GUID -> DDS topic, the same writers

    def discover():
        for s in publications.take(N=64):
            if not s.sample_info.valid_data or s.participant_key == dp.guid:
                continue
            seen_topics[s.topic_name] = s.type_name
            seen_writers[s.key.bytes] = s.topic_name

    # 2. Writers, as a camera driver and odometry would publish.
    images = DataWriter(dp, Topic(dp, "rt/image_raw", Image), qos=qos_writer(8))
    infos = DataWriter(dp, Topic(dp, "rt/camera_info", CameraInfo), qos=qos_writer(8))
    odom = DataWriter(dp, Topic(dp, "rt/odom", Odometry), qos=qos_writer(8))
    t0 = time.monotonic()
    for w, name in [(images, "image_raw"), (infos, "camera_info"), (odom, "odom")]:
        wait_until(f"the node's reader of {name}",
                   lambda w=w: w.get_publication_matched_status().current_count > 0,
                   30.0, alive)
    for name in ["tf", "diagnostics", "formation/annotations"]:
        r = streams[name].reader
        wait_until(f"the node's writer of {name}",
                   lambda r=r: r.get_subscription_matched_status().current_count > 0,
                   30.0, alive)
    matched_s = time.monotonic() - t0
    # The node's side may learn of our writers a moment after ours learnt of its readers.
    time.sleep(0.5)

    k_cam = m["k"]
    p = [k_cam[0], k_cam[1], k_cam[2], 0.0,
         k_cam[3], k_cam[4], k_cam[5], 0.0,
         k_cam[6], k_cam[7], k_cam[8], 0.0]
    base_ns = int(time.time()) * 1_000_000_000
    stamps = {}
    sent = 0
    start = time.monotonic()
    for k, frame in enumerate(m["frames"]):
        if not alive():
            break
        ns = base_ns + round(k * 1e9 / fps)
        stamps[ns] = k
        stamp = Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)
        with open(frame["path"], "rb") as f:
            pixels = f.read()
        if len(pixels) != m["width"] * m["height"]:
            raise Failure(f"{frame['path']}: {len(pixels)} bytes, not {m['width']}x{m['height']}")
        # Sleep to the frame's time, reading what arrived meanwhile.
        while True:
            for s in streams.values():
                s.poll()
            discover()
            wait = start + k / fps - time.monotonic()
            if wait <= 0:
                break
            time.sleep(min(wait, 0.005))
        o = Odometry(header=Header(stamp=stamp, frame_id="odom"), child_frame_id="base_link")
        o.twist.twist.linear.x = float(frame["v2"])
        o.twist.twist.angular.z = float(frame["w2"])
        odom.write(o)
        infos.write(CameraInfo(
            header=Header(stamp=stamp, frame_id="camera"),
            height=m["height"], width=m["width"],
            distortion_model=m["distortion_model"], d=list(m["d"]), k=list(k_cam),
            r=[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0], p=p,
        ))
        images.write(Image(
            header=Header(stamp=stamp, frame_id="camera"),
            height=m["height"], width=m["width"], encoding="mono8", is_bigendian=0,
            step=m["width"], data=pixels,
        ))
        sent += 1
    publish_s = time.monotonic() - start
    # The node exits on its own after --max-frames; then read what is still on its way.
    wait_until(f"the node to exit after {sent} frames (it tracks --max-frames of them)",
               lambda: not alive(), 30.0, lambda: True)
    quiet_since = time.monotonic()
    last = -1
    while time.monotonic() - quiet_since < 0.5:
        for s in streams.values():
            s.poll()
        discover()
        total = sum(s.received for s in streams.values())
        if total != last:
            last, quiet_since = total, time.monotonic()
        time.sleep(0.02)

    with open(m["node_jsonl"]) as f:
        lines = [json.loads(l) for l in f if l.strip()]
    return check(m, streams, seen_topics, seen_writers, lines, stamps, base_ns, fps,
                 {"frames_sent": sent, "publish_s": publish_s, "matched_s": matched_s})


def check(m, streams, seen_topics, seen_writers, lines, stamps, base_ns, fps, timing):
    tol = 1e-12
    problems = []
    notes = []
    if not lines:
        raise Failure("the node printed no JSON line")

    # Every topic the node publishes is one of ours, under the same type name.
    ours = {s.dds_topic: s.kind.__idl_typename__ for s in streams.values()}
    replies = sorted(t for t in seen_topics if t.startswith("rr/"))
    for topic, type_name in sorted(seen_topics.items()):
        if topic in replies:
            # The node's parameter services' reply writers: they write only in answer to a
            # request, and none is made here.
            if "::srv::dds_::" not in type_name:
                problems.append(f"{topic}: a service reply of type {type_name}")
        elif topic not in ours:
            problems.append(f"the node publishes {topic} ({type_name}), which is not read")
        elif type_name != ours[topic]:
            problems.append(f"{topic}: the node's type is {type_name}, ROS 2's is {ours[topic]}")

    for s in streams.values():
        for f in s.failures[:3]:
            problems.append(f"{s.label}: {f}")

    # The node's lines, by the frame they came from: `source` is `image_raw#SEQ`, the
    # writer's sequence number of the image, from 1 (our k + 1).
    by_k = {}
    for line in lines:
        src = line.get("source", "")
        try:
            k = int(src.rsplit("#", 1)[1]) - 1
        except (IndexError, ValueError):
            raise Failure(f"node line {line.get('frame')}: source {src!r} has no sequence number")
        by_k[k] = line
    k_first = min(by_k)
    first_ns = base_ns + round(k_first * 1e9 / fps)
    for k, line in by_k.items():
        ns = base_ns + round(k * 1e9 / fps)
        if abs(line["t"] - (ns - first_ns) * 1e-9) > 1e-9:
            problems.append(f"node frame {line['frame']}: t = {line['t']} but the image was "
                            f"stamped {(ns - first_ns) * 1e-9} s after the first")

    def frame_of(ns, where):
        k = stamps.get(ns)
        if k is None:
            raise Failure(f"{where}: stamp {ns} ns is none we sent")
        if k not in by_k:
            raise Failure(f"{where}: frame {k} has no line from the node")
        return k

    def leader_of(k, robot, where):
        for l in by_k[k]["leaders"]:
            if l["robot"] == robot:
                return l
        raise Failure(f"{where}: robot {robot} is not in the node's line for frame {k}")

    # What the node published per topic (frames, from its lines) against what arrived.
    accounts = {}

    k_last = max(by_k)
    strict = bool(m.get("strict"))

    def account(name, published, got):
        """`published`: the frames the node's lines say it published `name` for; `got`:
        the frames of the messages received."""
        published = sorted(published)
        dup = len(got) - len(set(got))
        missing = sorted(set(published) - set(got))
        # Two losses are the node's, not the interop's, and are tolerated (and reported):
        # - a leader's topics get their writers when the leader first appears, and the
        #   node publishes on them at once; RustDDS matches a new writer with the readers
        #   it already knows in its discovery thread, after the write, so the first
        #   message can reach no one (the writer then sends a GAP for it);
        # - with --max-frames the node exits right after publishing its last frame, and
        #   RustDDS may not have sent that frame's messages yet.
        at_start = [k for k in missing if k == published[0] and (not got or k < min(got))]
        at_exit = [k for k in missing if k == k_last]
        rest = [k for k in missing if k not in at_start and k not in at_exit]
        accounts[name] = {"expected": len(published), "lost_at_start": len(at_start),
                          "lost_at_exit": len(at_exit)}
        if dup:
            problems.append(f"/{name}: {dup} messages twice")
        if strict:
            rest += at_start + at_exit
            at_start, at_exit = [], []
        if rest:
            problems.append(f"/{name}: no message for frames {sorted(rest)[:10]}"
                            f"{' ...' if len(rest) > 10 else ''} of {len(published)}")
        if at_start:
            notes.append(f"/{name}: the message of frame {at_start[0]} (the leader's first) "
                         "was written before the new writer matched our reader")
        if at_exit:
            notes.append(f"/{name}: the message of frame {k_last} (the last) was not sent "
                         "before the node exited")

    status_code = {"tracking": 0.0, "coasting": 1.0, "lost": 2.0}
    worst = 0.0
    compared = 0
    for n in m["leader_ids"]:
        frames_with = [k for k, l in by_k.items() if any(x["robot"] == n for x in l["leaders"])]
        base = f"formation/leader_{n}"
        # The formation arrays against the node's lines.
        got = []
        for i, msg in enumerate(streams[f"{base}/formation"].samples):
            d = msg.data
            where = f"{base}/formation #{i}"
            if len(d) != 35:
                problems.append(f"{where}: {len(d)} values, not 35")
                continue
            dims = [(x.size, x.stride) for x in msg.layout.dim]
            if dims != [(7, 35), (5, 5)]:
                problems.append(f"{where}: layout {dims}")
            # Row 0's stamp is seconds since the epoch as a double: the nearest frame.
            k = round((d[0] - base_ns * 1e-9) * fps)
            ns = base_ns + round(k * 1e9 / fps)
            if abs(ns * 1e-9 - d[0]) > 1e-6:
                problems.append(f"{where}: stamp {d[0]!r} is no frame's")
                continue
            k = frame_of(ns, where)
            got.append(k)
            lead = leader_of(k, n, where)
            want = [float(n), status_code[lead["status"]], lead["since_seen"], lead["l12_std"],
                    lead["l12"], lead["alpha12"], lead["beta12"], lead["v1"], lead["w1"]]
            want += [x for row in lead["covariance"] for x in row]
            for j, (value, w) in enumerate(zip(d[1:], want)):
                err = abs(value - w)
                worst = max(worst, err)
                compared += 1
                if not err <= tol:
                    problems.append(f"{where} (frame {k}) value {j + 1}: {value!r}, "
                                    f"node's JSON {w!r}")
                    break
            cov = [d[10 + 5 * r: 15 + 5 * r] for r in range(5)]
            for r in range(5):
                for c in range(r):
                    if abs(cov[r][c] - cov[c][r]) > tol * max(1.0, abs(cov[r][c])):
                        problems.append(f"{where}: covariance not symmetric at ({r}, {c})")
        account(f"{base}/formation", frames_with, got)
        for suffix, frame_id in (("pose", "camera"), ("pose_base", "base_link")):
            got = []
            for i, msg in enumerate(streams[f"{base}/{suffix}"].samples):
                where = f"{base}/{suffix} #{i}"
                got.append(frame_of(stamp_ns_of(msg.header.stamp), where))
                if msg.header.frame_id != frame_id:
                    problems.append(f"{where}: frame_id {msg.header.frame_id!r}, not {frame_id!r}")
                c = msg.pose.covariance
                if any(abs(c[6 * r + q] - c[6 * q + r]) > tol * max(1.0, abs(c[6 * r + q]))
                       for r in range(6) for q in range(r)):
                    problems.append(f"{where}: covariance not symmetric")
                if any(c[7 * r] < 0 for r in range(6)):
                    problems.append(f"{where}: negative variance")
                q = msg.pose.pose.orientation
                if abs(math.hypot(q.x, q.y, q.z, q.w) - 1.0) > 1e-9:
                    problems.append(f"{where}: quaternion norm {math.hypot(q.x, q.y, q.z, q.w)}")
            account(f"{base}/{suffix}", frames_with, got)
        got = []
        for i, msg in enumerate(streams[f"{base}/twist"].samples):
            where = f"{base}/twist #{i}"
            k = frame_of(stamp_ns_of(msg.header.stamp), where)
            got.append(k)
            lead = leader_of(k, n, where)
            t = msg.twist.twist
            for value, w in ((t.linear.x, lead["v1"]), (t.angular.z, lead["w1"])):
                worst = max(worst, abs(value - w))
                compared += 1
                if not abs(value - w) <= tol:
                    problems.append(f"{where} (frame {k}): {value!r}, node's JSON {w!r}")
            if msg.header.frame_id != f"leader_{n}":
                problems.append(f"{where}: frame_id {msg.header.frame_id!r}")
        account(f"{base}/twist", frames_with, got)
    # /tf: one message per frame with a leader, base_link -> leader_N for each.
    got = []
    for i, msg in enumerate(streams["tf"].samples):
        ks = {frame_of(stamp_ns_of(t.header.stamp), f"tf #{i}") for t in msg.transforms}
        if len(ks) != 1:
            problems.append(f"tf #{i}: {len(msg.transforms)} transforms of frames {sorted(ks)}")
            continue
        k = ks.pop()
        got.append(k)
        want = sorted(f"leader_{l['robot']}" for l in by_k[k]["leaders"])
        have = sorted(t.child_frame_id for t in msg.transforms)
        if have != want or any(t.header.frame_id != "base_link" for t in msg.transforms):
            problems.append(f"tf #{i} (frame {k}): base_link -> {have}, the node's leaders {want}")
    account("tf", [k for k, l in by_k.items() if l["leaders"]], got)
    # Annotations: one message per tracked frame, one outline (a loop of 4 corners) and one
    # label per marker read; a frame without markers gives an empty message (no stamp).
    got = []
    empty = 0
    for i, msg in enumerate(streams["formation/annotations"].samples):
        where = f"formation/annotations #{i}"
        for p in msg.points:
            if p.type != 2 or len(p.points) != 4:
                problems.append(f"{where}: outline type {p.type}, {len(p.points)} points")
                break
        ks = {frame_of(stamp_ns_of(a.timestamp), where) for a in list(msg.points) + list(msg.texts)}
        if not ks:
            empty += 1
            continue
        if len(ks) != 1:
            problems.append(f"{where}: items of frames {sorted(ks)}")
            continue
        k = ks.pop()
        got.append(k)
        if len(msg.points) != by_k[k]["markers"] or len(msg.texts) != by_k[k]["markers"]:
            problems.append(f"{where} (frame {k}): {len(msg.points)} outlines and "
                            f"{len(msg.texts)} labels, the node read {by_k[k]['markers']} markers")
    account("formation/annotations", [k for k, l in by_k.items() if l["markers"] > 0], got)
    without = sum(1 for l in by_k.values() if l["markers"] == 0)
    if empty != without:
        problems.append(f"formation/annotations: {empty} empty messages, "
                        f"{without} frames without markers")
    accounts["formation/annotations"]["expected"] += without
    # Diagnostics: at least one, with the node's figures.
    diag_tracked = 0
    for i, msg in enumerate(streams["diagnostics"].samples):
        if len(msg.status) != 1:
            problems.append(f"diagnostics #{i}: {len(msg.status)} statuses")
            continue
        values = {kv.key: kv.value for kv in msg.status[0].values}
        if "frames_tracked" not in values:
            problems.append(f"diagnostics #{i}: no frames_tracked among {sorted(values)}")
            continue
        diag_tracked = max(diag_tracked, int(values["frames_tracked"]))
    if diag_tracked > len(by_k):
        problems.append(f"diagnostics: frames_tracked {diag_tracked} > {len(by_k)} lines")
    # The other direction: fed by CycloneDDS, the node computes what `track` computes from
    # the files (pixels, calibration and inputs all read exactly), when it took every frame.
    track_worst = None
    if m.get("track_jsonl"):
        with open(m["track_jsonl"]) as f:
            track = [json.loads(l) for l in f if l.strip()]
        if sorted(by_k) != list(range(len(by_k))) or len(track) < len(by_k):
            notes.append("the node did not take frames 0.. in a row: not compared with track")
        else:
            track_worst = 0.0
            for k, line in by_k.items():
                want = track[k]["leaders"]
                if [(l["robot"], l["status"]) for l in line["leaders"]] != \
                        [(l["robot"], l["status"]) for l in want]:
                    problems.append(f"frame {k}: the node's leaders {line['leaders']!r:.80} "
                                    f"differ from track's")
                    continue
                for a, b in zip(line["leaders"], want):
                    for key in ("l12", "alpha12", "beta12", "v1", "w1", "l12_std", "alpha12_std",
                                "beta12_std", "v1_std", "w1_std"):
                        track_worst = max(track_worst, abs(a[key] - b[key]))
                    for ra, rb in zip(a["covariance"], b["covariance"]):
                        track_worst = max(track_worst, max(abs(x - y) for x, y in zip(ra, rb)))
                    # Times: track counts frame / fps, the node whole nanoseconds of stamps.
                    if abs(a["since_seen"] - b["since_seen"]) > 2e-9:
                        problems.append(f"frame {k}: since_seen {a['since_seen']!r}, "
                                        f"track's {b['since_seen']!r}")
            if track_worst > tol:
                problems.append(f"the node's estimates differ from track's on the same frames "
                                f"by up to {track_worst:.3g}")

    # ROS 2's graph: the node is listed, with every writer it has on a topic we read.
    infos = streams["ros_discovery_info"].samples
    listed = {}
    for info in infos:
        for node in info.node_entities_info_seq:
            listed[(node.node_namespace, node.node_name)] = {bytes(g.data) for g in node.writer_gid_seq}
    writers = listed.get(("/", "formation_tracker"))
    if writers is None:
        problems.append(f"ros_discovery_info: the node formation_tracker is not listed "
                        f"({sorted(listed)})")
    else:
        unlisted = sorted({t for g, t in seen_writers.items()
                           if t.startswith("rt/") and g not in writers})
        if unlisted:
            problems.append(f"ros_discovery_info: the node's writers on {unlisted} are not listed")

    rows = []
    for name, s in streams.items():
        acc = accounts.get(name, {})
        if name.startswith("formation/leader_") and not acc.get("expected") and not s.received:
            continue  # a leader id the recording never shows
        rows.append({
            "topic": s.label,
            "type": s.kind.__idl_typename__,
            "received": s.received,
            "decoded": len(s.samples),
            "expected": acc.get("expected"),
            "lost_at_start": acc.get("lost_at_start", 0),
            "lost_at_exit": acc.get("lost_at_exit", 0),
            "encodings": sorted(s.encodings),
        })
        # parameter_events: ROS 2's, published only when a parameter changes.
        if s.received == 0 and name != "parameter_events":
            problems.append(f"{s.label}: no message received")
    if compared == 0:
        problems.append("no formation value compared")

    summary = {
        "topics": rows,
        "node_lines": len(lines),
        "first_frame": k_first,
        "values_compared": compared,
        "max_abs_difference": worst,
        "track_max_abs_difference": track_worst,
        "publications_seen": seen_topics,
        "notes": notes,
        "service_replies": replies,
        **timing,
    }
    print_table(summary)
    if problems:
        more = f" (and {len(problems) - 1} more)" if len(problems) > 1 else ""
        for p in problems[1:10]:
            print(f"  also: {p}", flush=True)
        raise Failure(problems[0] + more)
    return summary


def print_table(s):
    print(f"{'topic (node -> CycloneDDS)':<31} {'type':<53} {'received':>8} {'decoded':>7} "
          f"{'published':>9} {'lost: start':>11} {'exit':>4}")
    for r in s["topics"]:
        want = "-" if r["expected"] is None else str(r["expected"])
        print(f"{r['topic']:<31} {r['type']:<53} {r['received']:>8} {r['decoded']:>7} "
              f"{want:>9} {r['lost_at_start']:>11} {r['lost_at_exit']:>4}")
    print(f"frames published: {s['frames_sent']} in {s['publish_s']:.1f} s; node lines: "
          f"{s['node_lines']}; formation/twist values compared with the node's JSON: "
          f"{s['values_compared']}, largest difference {s['max_abs_difference']:.3g}", flush=True)
    if s["track_max_abs_difference"] is not None:
        print(f"node (fed by CycloneDDS) against track on the same files: {s['node_lines']} "
              f"frames, largest difference {s['track_max_abs_difference']:.3g}", flush=True)
    if s["service_replies"]:
        print(f"not read: {len(s['service_replies'])} service reply writers of the node "
              f"(parameter services; they write only in answer to a request)", flush=True)
    for note in s["notes"]:
        print(f"note: {note}", flush=True)


if __name__ == "__main__":
    sys.exit(main())
