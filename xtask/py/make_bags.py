"""Writes the fixture bags from a manifest made by `cargo xtask bags`.

An implementation independent of ours writes them: `mcap-ros2-support` (single-file bags
with zstd or lz4 chunks) and `rosbags` (a rosbag2 folder with metadata.yaml). Run only from
`cargo xtask bags`, in the virtual environment it makes under target/.
"""

import json
import sys
from pathlib import Path

from mcap.writer import CompressionType
from mcap_ros2.writer import Writer

HEADER = """std_msgs/Header header
"""
STD_HEADER = """================================================================================
MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id
================================================================================
MSG: builtin_interfaces/Time
int32 sec
uint32 nanosec
"""
IMAGE = HEADER + """uint32 height
uint32 width
string encoding
uint8 is_bigendian
uint32 step
uint8[] data
""" + STD_HEADER
COMPRESSED = HEADER + """string format
uint8[] data
""" + STD_HEADER
CAMERA_INFO = HEADER + """uint32 height
uint32 width
string distortion_model
float64[] d
float64[9] k
float64[9] r
float64[12] p
uint32 binning_x
uint32 binning_y
sensor_msgs/RegionOfInterest roi
================================================================================
MSG: sensor_msgs/RegionOfInterest
uint32 x_offset
uint32 y_offset
uint32 height
uint32 width
bool do_rectify
""" + STD_HEADER
ODOMETRY = HEADER + """string child_frame_id
geometry_msgs/PoseWithCovariance pose
geometry_msgs/TwistWithCovariance twist
================================================================================
MSG: geometry_msgs/PoseWithCovariance
geometry_msgs/Pose pose
float64[36] covariance
================================================================================
MSG: geometry_msgs/Pose
geometry_msgs/Point position
geometry_msgs/Quaternion orientation
================================================================================
MSG: geometry_msgs/Point
float64 x
float64 y
float64 z
================================================================================
MSG: geometry_msgs/Quaternion
float64 x
float64 y
float64 z
float64 w
================================================================================
MSG: geometry_msgs/TwistWithCovariance
geometry_msgs/Twist twist
float64[36] covariance
================================================================================
MSG: geometry_msgs/Twist
geometry_msgs/Vector3 linear
geometry_msgs/Vector3 angular
================================================================================
MSG: geometry_msgs/Vector3
float64 x
float64 y
float64 z
""" + STD_HEADER


def header(stamp_ns, frame_id="camera"):
    return {
        "stamp": {"sec": stamp_ns // 1_000_000_000, "nanosec": stamp_ns % 1_000_000_000},
        "frame_id": frame_id,
    }


def camera_info(stamp_ns, width, height, k):
    p = [k[0], k[1], k[2], 0.0, k[3], k[4], k[5], 0.0, k[6], k[7], k[8], 0.0]
    return {
        "header": header(stamp_ns),
        "height": height,
        "width": width,
        "distortion_model": "plumb_bob",
        "d": [0.0, 0.0, 0.0, 0.0, 0.0],
        "k": k,
        "r": [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
        "p": p,
        "binning_x": 0,
        "binning_y": 0,
        "roi": {"x_offset": 0, "y_offset": 0, "height": 0, "width": 0, "do_rectify": False},
    }


def odometry(stamp_ns, v, w):
    zero3 = {"x": 0.0, "y": 0.0, "z": 0.0}
    return {
        "header": header(stamp_ns, "odom"),
        "child_frame_id": "base_link",
        "pose": {
            "pose": {"position": zero3, "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}},
            "covariance": [0.0] * 36,
        },
        "twist": {
            "twist": {"linear": {"x": v, "y": 0.0, "z": 0.0}, "angular": {"x": 0.0, "y": 0.0, "z": w}},
            "covariance": [0.0] * 36,
        },
    }


def mcap_bag(path, compression, frames, width, height, k, encoding):
    """One .mcap file: camera_info, odometry and images, in recording order."""
    with open(path, "wb") as f:
        writer = Writer(f, chunk_size=1 << 20, compression=compression)
        s_info = writer.register_msgdef("sensor_msgs/msg/CameraInfo", CAMERA_INFO)
        s_odom = writer.register_msgdef("nav_msgs/msg/Odometry", ODOMETRY)
        if encoding == "png":
            s_img = writer.register_msgdef("sensor_msgs/msg/CompressedImage", COMPRESSED)
        else:
            s_img = writer.register_msgdef("sensor_msgs/msg/Image", IMAGE)
        for fr in frames:
            t = fr["stamp_ns"]
            writer.write_message("/camera/camera_info", s_info, camera_info(t, width, height, k), log_time=t, publish_time=t)
            if "v2" in fr:
                writer.write_message("/odom", s_odom, odometry(t, fr["v2"], fr["w2"]), log_time=t, publish_time=t)
            data = Path(fr["path"]).read_bytes()
            if encoding == "png":
                msg = {"header": header(t), "format": "png", "data": data}
            else:
                bpp = {"mono8": 1, "rgb8": 3}[encoding]
                msg = {
                    "header": header(t), "height": height, "width": width, "encoding": encoding,
                    "is_bigendian": 0, "step": width * bpp, "data": data,
                }
            writer.write_message("/camera/image_raw" if encoding != "png" else "/camera/image_raw/compressed", s_img, msg, log_time=t, publish_time=t)
        writer.finish()


def rosbag2_folder(path, frames, width, height, k):
    """A rosbag2 folder (metadata.yaml + .mcap) written by `rosbags`, with compressed images."""
    from rosbags.rosbag2 import StoragePlugin, Writer as BagWriter
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    Time = ts.types["builtin_interfaces/msg/Time"]
    Header = ts.types["std_msgs/msg/Header"]
    Compressed = ts.types["sensor_msgs/msg/CompressedImage"]
    Info = ts.types["sensor_msgs/msg/CameraInfo"]
    Roi = ts.types["sensor_msgs/msg/RegionOfInterest"]
    import numpy as np

    def hdr(t):
        return Header(stamp=Time(sec=t // 1_000_000_000, nanosec=t % 1_000_000_000), frame_id="camera")

    with BagWriter(path, version=8, storage_plugin=StoragePlugin.MCAP) as w:
        c_img = w.add_connection("/camera/image_raw/compressed", Compressed.__msgtype__, typestore=ts)
        c_info = w.add_connection("/camera/camera_info", Info.__msgtype__, typestore=ts)
        for fr in frames:
            t = fr["stamp_ns"]
            info = Info(
                header=hdr(t), height=height, width=width, distortion_model="plumb_bob",
                d=np.zeros(5), k=np.array(k), r=np.eye(3).flatten(),
                p=np.array([k[0], k[1], k[2], 0.0, k[3], k[4], k[5], 0.0, k[6], k[7], k[8], 0.0]),
                binning_x=0, binning_y=0,
                roi=Roi(x_offset=0, y_offset=0, height=0, width=0, do_rectify=False),
            )
            w.write(c_info, t, ts.serialize_cdr(info, Info.__msgtype__))
            data = np.frombuffer(Path(fr["path"]).read_bytes(), dtype=np.uint8)
            img = Compressed(header=hdr(t), format="png", data=data)
            w.write(c_img, t, ts.serialize_cdr(img, Compressed.__msgtype__))


def main():
    manifest = json.loads(Path(sys.argv[1]).read_text())
    for bag in manifest["bags"]:
        out = Path(bag["out"])
        if bag["kind"] == "rosbag2":
            import shutil
            if out.exists():
                shutil.rmtree(out)
            rosbag2_folder(out, bag["frames"], bag["width"], bag["height"], bag["k"])
        else:
            compression = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4}[bag["kind"]]
            mcap_bag(out, compression, bag["frames"], bag["width"], bag["height"], bag["k"], bag["encoding"])
        print(f"make_bags: wrote {out}")


if __name__ == "__main__":
    main()
