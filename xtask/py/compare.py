"""The peers of `cargo xtask compare` (run by it in target/py-venv; not by cargo test).

argv[1]: the manifest written by xtask/src/compare.rs (frames, real frames, pose cases,
filter runs); argv[2]: the results (JSON). Every timing is single-threaded, with
time.perf_counter; the scoring is done in Rust, with the same code as ours.
"""

import json
import math
import platform
import sys
import time
from importlib import metadata

import cv2
import numpy as np
import pupil_apriltags

import polar_ukf

cv2.setNumThreads(1)
manifest = json.load(open(sys.argv[1]))
REPS = manifest["reps"]


def median(v):
    return float(np.median(np.array(v))) if v else float("nan")


# ---------------------------------------------------------------------------- detection

def aruco_detector(dict_id, mode, width, height):
    params = cv2.aruco.DetectorParameters()
    if mode == "subpix":
        params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    elif mode == "aruco3":
        params.useAruco3Detection = True
        # ArUco3 gains its speed by searching a downscaled image for markers no smaller
        # than a ratio of the frame: the smallest settings that still read most markers of
        # 20-40 px (a canonical side of 16 px, a ratio of 6.4 px over the frame's larger
        # side); OpenCV's defaults (32 px, ratio 0) read fewer small markers.
        params.minSideLengthCanonicalImg = 16
        params.minMarkerLengthRatioOriginalImg = 6.4 / max(width, height)
    else:
        params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_NONE
    return cv2.aruco.ArucoDetector(cv2.aruco.getPredefinedDictionary(dict_id), params)


def run_aruco(det, img):
    corners, ids, _ = det.detectMarkers(img)
    out = []
    if ids is not None:
        for c, i in zip(corners, ids.reshape(-1)):
            out.append([int(i), c.reshape(4, 2).tolist()])
    return out


APRIL = {}


def april(decimate):
    if decimate not in APRIL:
        APRIL[decimate] = pupil_apriltags.Detector(
            families="tag36h11", nthreads=1, quad_decimate=float(decimate), quad_sigma=0.0,
            refine_edges=1, decode_sharpening=0.25)
    return APRIL[decimate]


def run_april(det, img):
    return [[int(d.tag_id), np.asarray(d.corners).reshape(4, 2).tolist()] for d in det.detect(img)]


def timed(fn, img):
    out = fn(img)  # warm-up
    times, cpu = [], []
    for _ in range(REPS):
        t, c = time.perf_counter(), time.thread_time()
        out = fn(img)
        cpu.append(time.thread_time() - c)
        times.append(time.perf_counter() - t)
    return {"markers": out, "seconds": median(times), "cpu": median(cpu)}


ARUCO_MODES = {"aruco_none": "none", "aruco_subpix": "subpix", "aruco3": "aruco3"}
EMPTY = {"markers": [], "seconds": None, "cpu": None}


def detect_frame(key, img, dict_id):
    h, w = img.shape
    if key in ARUCO_MODES:
        det = aruco_detector(dict_id, ARUCO_MODES[key], w, h)
        return timed(lambda im: run_aruco(det, im), img)
    det = april(1 if key == "apriltag_d1" else 2)
    return timed(lambda im: run_april(det, im), img)


KEYS = ["aruco_none", "aruco_subpix", "aruco3", "apriltag_d1", "apriltag_d2"]
detection = {k: [] for k in KEYS}
for i, f in enumerate(manifest["frames"]):
    img = cv2.imread(f["path"], cv2.IMREAD_GRAYSCALE)
    for k in KEYS:
        if k.startswith("aruco") and f["family"] == "aruco4x4":
            detection[k].append(detect_frame(k, img, cv2.aruco.DICT_4X4_100))
        elif k.startswith("apriltag") and f["family"] == "tag36h11":
            detection[k].append(detect_frame(k, img, None))
        else:
            detection[k].append(EMPTY)
    if i % 50 == 0:
        print(f"compare.py: frame {i + 1}/{len(manifest['frames'])}", file=sys.stderr)

real = {k: [] for k in KEYS}
for f in manifest["real"]:
    img = cv2.imread(f["path"], cv2.IMREAD_GRAYSCALE)
    for k in KEYS:
        real[k].append(detect_frame(k, img, cv2.aruco.DICT_APRILTAG_36h11))

# The real photographs: AprilTag 3 (tag36h11, decimate 1) and OpenCV ArUco with default
# parameters in two dictionaries.
PHOTO_ARUCO = {"aruco_4x4_50": cv2.aruco.DICT_4X4_50, "aruco_6x6_250": cv2.aruco.DICT_6X6_250}
photos = {k: [] for k in ["apriltag_d1", *PHOTO_ARUCO]}
for f in manifest["photos"]:
    img = cv2.imread(f["path"], cv2.IMREAD_GRAYSCALE)
    photos["apriltag_d1"].append(timed(lambda im: run_april(april(1), im), img))
    for key, dict_id in PHOTO_ARUCO.items():
        det = cv2.aruco.ArucoDetector(cv2.aruco.getPredefinedDictionary(dict_id),
                                      cv2.aruco.DetectorParameters())
        photos[key].append(timed(lambda im: run_aruco(det, im), img))

# ---------------------------------------------------------------------------- pose

pose_in = manifest["pose"]
K = np.array(pose_in["k"], dtype=np.float64).reshape(3, 3)
s = pose_in["side"]
OBJ = np.array([[-s / 2, s / 2, 0], [s / 2, s / 2, 0], [s / 2, -s / 2, 0], [-s / 2, -s / 2, 0]],
               dtype=np.float64)
NODIST = np.zeros(5)
FLAGS = {"ippe_square": cv2.SOLVEPNP_IPPE_SQUARE, "sqpnp": cv2.SOLVEPNP_SQPNP,
         "iterative": cv2.SOLVEPNP_ITERATIVE}
pts = [np.array(c["corners"], dtype=np.float64).reshape(4, 1, 2) for c in pose_in["cases"]]
pose = {}
for name, flag in FLAGS.items():
    poses = []
    for p in pts:
        try:
            ok, r, t = cv2.solvePnP(OBJ, p, K, NODIST, flags=flag)
            poses.append([r.reshape(-1).tolist(), t.reshape(-1).tolist()] if ok else None)
        except cv2.error:
            poses.append(None)
    times = []
    for _ in range(pose_in["reps"]):
        t0 = time.perf_counter()
        for p in pts:
            try:
                cv2.solvePnP(OBJ, p, K, NODIST, flags=flag)
            except cv2.error:
                pass
        times.append((time.perf_counter() - t0) / max(len(pts), 1))
    pose[name] = {"poses": poses, "seconds": median(times)}
pose["reps"] = pose_in["reps"]

# ---------------------------------------------------------------------------- filter

filters = []
for run in manifest["filter"]:
    try:
        t0 = time.perf_counter()
        est = polar_ukf.run(run)
        elapsed = time.perf_counter() - t0
        filters.append({"seed": run["seed"], "estimates": est,
                        "seconds_per_step": elapsed / max(len(est), 1)})
    except Exception as e:  # a failed run is reported, not fatal
        print(f"compare.py: filterpy failed on seed {run['seed']}: {e}", file=sys.stderr)
        filters.append({"seed": run["seed"], "error": str(e)})

versions = {}
for pkg in ["opencv-contrib-python-headless", "pupil-apriltags", "filterpy", "numpy", "scipy"]:
    try:
        versions[pkg] = metadata.version(pkg)
    except metadata.PackageNotFoundError:
        versions[pkg] = "not installed"
versions["OpenCV (cv2.__version__)"] = cv2.__version__

json.dump({
    "python": platform.python_version(),
    "versions": versions,
    "detection": detection,
    "real": real,
    "photos": photos,
    "pose": pose,
    "filter": filters,
}, open(sys.argv[2], "w"))
