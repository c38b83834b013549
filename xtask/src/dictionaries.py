# Run by `cargo xtask dictionaries` inside target/py-venv (see xtask/src/dictionaries.rs).
#
# Reads every predefined dictionary of OpenCV's aruco module and writes, to argv[1], one JSON
# object: the OpenCV version and, per dictionary, its OpenCV name and enum value, marker size,
# maxCorrectionBits and codes. Codes use fiducial's convention: bit k = row * n + col of the
# data grid (row 0 at the top, col 0 at the left, as generateImageMarker draws marker 0 turns),
# black = 1. OpenCV's own bit matrix (getBitsFromByteList) has white = 1; that is checked here
# against the image OpenCV draws, so the convention is verified, not assumed.
#
# Also writes cross-check marker PNGs (generateImageMarker, 10 px per cell, borderBits 1, no
# quiet zone) of a few ids per dictionary into argv[2]/<name>/<id>.png.
import json
import os
import sys

import cv2
import numpy as np

aruco = cv2.aruco

NAMES = [
    "DICT_4X4_50", "DICT_4X4_100", "DICT_4X4_250", "DICT_4X4_1000",
    "DICT_5X5_50", "DICT_5X5_100", "DICT_5X5_250", "DICT_5X5_1000",
    "DICT_6X6_50", "DICT_6X6_100", "DICT_6X6_250", "DICT_6X6_1000",
    "DICT_7X7_50", "DICT_7X7_100", "DICT_7X7_250", "DICT_7X7_1000",
    "DICT_ARUCO_ORIGINAL", "DICT_ARUCO_MIP_36h12",
    "DICT_APRILTAG_16h5", "DICT_APRILTAG_25h9", "DICT_APRILTAG_36h10", "DICT_APRILTAG_36h11",
]
PX = 10

out_json, out_png = sys.argv[1], sys.argv[2]
result = {"opencv_version": cv2.__version__, "dictionaries": []}
for name in NAMES:
    enum = getattr(aruco, name)
    d = aruco.getPredefinedDictionary(enum)
    n = int(d.markerSize)
    count = int(d.bytesList.shape[0])
    codes = []
    for i in range(count):
        bits = aruco.Dictionary.getBitsFromByteList(d.bytesList[i:i + 1], n)
        black = 1 - bits.astype(np.int64)
        # Verify the convention on OpenCV's own drawing: cell (r, c) of the data grid is the
        # image cell (r + 1, c + 1) of a one-cell-border marker, one pixel per cell.
        img = aruco.generateImageMarker(d, i, n + 2, borderBits=1)
        drawn = (img[1:n + 1, 1:n + 1] < 128).astype(np.int64)
        if not np.array_equal(drawn, black):
            sys.exit(f"{name} id {i}: OpenCV's bit matrix does not match its drawing")
        code = 0
        for k, b in enumerate(black.flatten().tolist()):
            code |= int(b) << k
        codes.append(code)
    result["dictionaries"].append({
        "name": name,
        "opencv_enum": int(enum),
        "marker_size": n,
        "max_correction_bits": int(d.maxCorrectionBits),
        "codes": codes,
    })
    folder = os.path.join(out_png, name)
    os.makedirs(folder, exist_ok=True)
    for i in sorted({0, count // 2, count - 1}):
        img = aruco.generateImageMarker(d, i, (n + 2) * PX, borderBits=1)
        cv2.imwrite(os.path.join(folder, f"{i}.png"), img)

with open(out_json, "w") as f:
    json.dump(result, f)
