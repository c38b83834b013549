"""AprilTag 3's corners on grey images, for `cargo xtask grazing`.

argv[1]: a JSON list of PGM paths; argv[2]: the output, a JSON list with one entry per
image, in `compare.py`'s form of a peer's reads: {"markers": [[id, [[x, y] x 4]], ...]}, in
AprilTag's pixel convention (pixel centres at half-integers). Detector: tag36h11, decimate 1, refine_edges on (the
settings of the NASA photo's reference reading).
"""
import json
import sys

import numpy as np
import pupil_apriltags


def read_pgm(path):
    """A binary PGM (P5, 8-bit) as written by the xtask: header fields, then the pixels."""
    data = open(path, "rb").read()
    fields, pos = [], 0
    while len(fields) < 4:
        while data[pos:pos + 1].isspace():
            pos += 1
        start = pos
        while not data[pos:pos + 1].isspace():
            pos += 1
        fields.append(data[start:pos])
    w, h = int(fields[1]), int(fields[2])
    return np.frombuffer(data[pos + 1:pos + 1 + w * h], dtype=np.uint8).reshape(h, w)


detector = pupil_apriltags.Detector(families="tag36h11", quad_decimate=1.0, refine_edges=True)
out = []
for path in json.load(open(sys.argv[1])):
    img = np.ascontiguousarray(read_pgm(path))
    out.append({"markers": [
        [int(d.tag_id), [[float(x), float(y)] for x, y in d.corners]]
        for d in detector.detect(img)
    ]})
json.dump(out, open(sys.argv[2], "w"))
