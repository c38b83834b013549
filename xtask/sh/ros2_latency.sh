#!/usr/bin/env bash
# The ROS 2 node's latency (docs/performance.md): `ros2-sim --replay` publishes a recording
# at 30 frames/s to `formation-tracker ros2`, the node pinned to one core and the publisher
# to another, inside a private network namespace (no packet leaves the machine). The node's
# last stderr line gives the latency from the image's arrival (the node wakes for it) to the
# publication of the frame's last message: median, 99th percentile and the stages' medians.
# Usage: xtask/sh/ros2_latency.sh BIN RECORDING_DIR [RUNS]
set -euo pipefail
BIN=$(realpath "$1"); REC=$(realpath "$2"); RUNS=${3:-3}
FRAMES=$(ls "$REC/frames" | wc -l)
exec unshare --user --map-root-user --net bash -s "$BIN" "$REC" "$RUNS" "$FRAMES" <<'INNER'
set -euo pipefail
BIN=$1; REC=$2; RUNS=$3; FRAMES=$4
ip link set lo up; ip link set lo multicast on; ip route add 224.0.0.0/4 dev lo
export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST ROS_DOMAIN_ID=32
err=$(mktemp)
for run in $(seq "$RUNS"); do
  taskset -c 0 "$BIN" ros2 -q --max-frames "$FRAMES" > /dev/null 2> "$err" & node=$!
  taskset -c 1 "$BIN" ros2-sim --replay "$REC" 2> /dev/null
  wait $node
  echo "run $run: $(tail -n 1 "$err")"
done
rm -f "$err"
INNER
