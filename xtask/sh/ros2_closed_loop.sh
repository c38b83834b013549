#!/usr/bin/env bash
# The loop closed across processes (docs/ros2.md): for each scenario file, `ros2-sim
# --scenario` simulates the robot pair and `ros2 --control` drives its follower over DDS,
# inside a private network namespace; then `demo --closed-loop` runs the same scenario in
# one process. Prints the RMS formation error after 3 s (true l12 and alpha12 against the
# demo follower's set-points) of both, and their ratio.
# Usage: xtask/sh/ros2_closed_loop.sh BIN SCENARIO.yaml...
set -euo pipefail
BIN=$(realpath "$1"); shift
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
for scenario in "$@"; do
  s=$(realpath "$scenario")
  "$BIN" ros2-sim --scenario "$s" --write-controller "$work/controller.yaml" 2> /dev/null
  unshare --user --map-root-user --net bash -s "$BIN" "$s" "$work" <<'INNER'
set -euo pipefail
BIN=$1; S=$2; W=$3
ip link set lo up; ip link set lo multicast on; ip route add 224.0.0.0/4 dev lo
export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST ROS_DOMAIN_ID=33
"$BIN" ros2 -q --control "$W/controller.yaml" > /dev/null 2> "$W/node.err" & node=$!
"$BIN" ros2-sim -q --scenario "$S" --truth "$W/truth.csv" 2> "$W/sim.err"
kill -INT $node; wait $node
INNER
  "$BIN" demo -q --closed-loop --scenario "$s" --out "$work/demo" > /dev/null 2>&1
  python3 - "$scenario" "$work/truth.csv" "$work/demo/series.csv" <<'PY'
import csv, math, sys
name, truth, series = sys.argv[1:]
t = list(csv.DictReader(open(truth)))
goal = {round(float(r["t"]), 4): (float(r["l12_desired"]), float(r["alpha12_desired"])) for r in t}
def rms(rows, l, a):
    rows = [r for r in rows if float(r["t"]) >= 3.0 - 1e-9]
    g = [goal[round(float(r["t"]), 4)] for r in rows]
    el = math.sqrt(sum((float(r[l]) - gl) ** 2 for r, (gl, _) in zip(rows, g)) / len(rows))
    ea = math.sqrt(sum((float(r[a]) - ga) ** 2 for r, (_, ga) in zip(rows, g)) / len(rows))
    return el, ea
ros = rms(t, "l12", "alpha12")
demo = rms([r for r in csv.DictReader(open(series)) if r["follower"] == "2"], "l12_true", "alpha12_true")
print(f"{name}: RMS error after 3 s, across processes l12 {ros[0]:.4f} m alpha12 {ros[1]:.4f} rad; "
      f"demo --closed-loop l12 {demo[0]:.4f} m alpha12 {demo[1]:.4f} rad; "
      f"ratio l12 {ros[0] / demo[0]:.2f}, alpha12 {ros[1] / demo[1]:.2f}")
PY
  tail -n 1 "$work/node.err"
done
