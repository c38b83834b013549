"""The filterpy UKF baseline of `cargo xtask dukf-table` (issue #30), run by it in
target/py-venv, never from cargo test.

argv[1]: the runs and the grid (JSON, written by xtask/src/dukf_table/held_out.rs): `runs`,
each as `polar_ukf.run` takes it without `q` and `rr`; `grid`, each point `{"q": [6], "rr":
[2]}` (per-step process noise diagonals). argv[2]: the results (JSON): `estimates[g][r]`, the
estimates of run r at grid point g (`polar_ukf.run`'s), or null where filterpy failed. The
scoring and the choice of the point are done in Rust, on the tuning seeds only.
"""

import json
import sys
from multiprocessing import Pool

import polar_ukf


def one(job):
    point, run = job
    try:
        return polar_ukf.run(dict(run, q=point["q"], rr=point["rr"]))
    except Exception as e:  # a failed run is reported, not fatal
        print(f"ukf_baseline.py: filterpy failed: {e}", file=sys.stderr)
        return None


if __name__ == "__main__":
    spec = json.load(open(sys.argv[1]))
    runs, grid = spec["runs"], spec["grid"]
    jobs = [(g, r) for g in grid for r in runs]
    with Pool(2) as pool:
        flat = pool.map(one, jobs, chunksize=4)
    n = len(runs)
    json.dump({"estimates": [flat[i * n:(i + 1) * n] for i in range(len(grid))]},
              open(sys.argv[2], "w"))
