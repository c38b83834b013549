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
from filterpy.kalman import MerweScaledSigmaPoints, UnscentedKalmanFilter

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

def wrap(a):
    return (a + math.pi) % (2 * math.pi) - math.pi if not (-math.pi < a <= math.pi) else a


STATE_ANGLES = (2, 4, 5)


def derivative(x, v2, w2, d):
    """PolarModel::derivative (spec 2.4) with the leader's velocities from the state."""
    _, _, th1, l, a, b, v1, w1 = x
    sa, ca = math.sin(a), math.cos(a)
    sb, cb = math.sin(b), math.cos(b)
    common = (-v1 * sa + v2 * sb) / l
    return np.array([v1 * math.cos(th1), v1 * math.sin(th1), w1,
                     v1 * ca - v2 * cb - d * w2 * sb,
                     common - w1 - d * w2 * cb / l,
                     common - w2 * (1.0 + d * cb / l), 0.0, 0.0])


def fx(x, dt, u=(0.0, 0.0), d=0.5):
    """PolarModel::f: one RK4 step with inputs held, angles wrapped; v1, w1 a random walk."""
    v2, w2 = u
    k1 = derivative(x, v2, w2, d)
    k2 = derivative(x + 0.5 * dt * k1, v2, w2, d)
    k3 = derivative(x + 0.5 * dt * k2, v2, w2, d)
    k4 = derivative(x + dt * k3, v2, w2, d)
    nxt = x + (k1 + 2 * k2 + 2 * k3 + k4) * (dt / 6.0)
    for i in STATE_ANGLES:
        nxt[i] = wrap(nxt[i])
    return nxt


def hx(x):
    return np.array([x[3], x[4], x[5]])


def residual_x(a, b):
    y = a - b
    for i in STATE_ANGLES:
        y[i] = wrap(y[i])
    return y


def residual_z(a, b):
    y = a - b
    y[1] = wrap(y[1])
    y[2] = wrap(y[2])
    return y


def circular_mean(sigmas, wm, angles):
    x = np.dot(wm, sigmas)
    for i in angles:
        x[i] = math.atan2(np.dot(wm, np.sin(sigmas[:, i])), np.dot(wm, np.cos(sigmas[:, i])))
    return x


filters = []
for run in manifest["filter"]:
    try:
        dt, d = run["dt"], run["d"]
        alpha, beta, kappa = run["ut"]
        points = MerweScaledSigmaPoints(8, alpha=alpha, beta=beta, kappa=kappa,
                                        subtract=residual_x)
        ukf = UnscentedKalmanFilter(
            dim_x=8, dim_z=3, dt=dt, hx=hx, fx=fx, points=points,
            x_mean_fn=lambda s, w: circular_mean(s, w, STATE_ANGLES),
            z_mean_fn=lambda s, w: circular_mean(s, w, (1, 2)),
            residual_x=residual_x, residual_z=residual_z)
        ukf.x = np.array(run["x0"] + run["w0"], dtype=np.float64)
        ukf.P = np.diag(run["p0"] + run["pw0"])
        ukf.Q = np.diag(run["q"] + run["rr"])
        ukf.R = np.diag(run["r"])
        est = []
        t0 = time.perf_counter()
        for z, u in zip(run["measurements"], run["inputs"]):
            ukf.predict(u=tuple(u), d=d)
            ukf.update(np.array(z))
            x = ukf.x
            est.append([float(x[3]), float(x[4]), float(x[5]), float(x[6]), float(x[7])])
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
    "pose": pose,
    "filter": filters,
}, open(sys.argv[2], "w"))
