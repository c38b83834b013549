#!/usr/bin/env bash
# The ROS 2 node's soak (docs/reliability.md): `ros2-sim --repeat 0` publishes a recording
# at 30 frames/s for MINUTES minutes to `formation-tracker ros2`, inside a private network
# namespace (no packet leaves the machine), and the node's resident memory is sampled every
# 10 s. Usage: xtask/sh/ros2_soak.sh BIN RECORDING_DIR MINUTES OUT_CSV
# (RECORDING_DIR as written by `formation-tracker demo --save-frames`).
set -euo pipefail
BIN=$(realpath "$1"); REC=$(realpath "$2"); MINUTES=$3; OUT=$(realpath -m "$4")
exec unshare --user --map-root-user --net bash -s "$BIN" "$REC" "$MINUTES" "$OUT" <<'INNER'
set -euo pipefail
BIN=$1; REC=$2; MINUTES=$3; OUT=$4
ip link set lo up; ip link set lo multicast on; ip route add 224.0.0.0/4 dev lo
export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST ROS_DOMAIN_ID=31
"$BIN" ros2 -q > /dev/null 2> "$OUT.node.err" & node=$!
"$BIN" ros2-sim --replay "$REC" --repeat 0 2> "$OUT.sim.err" & sim=$!
echo "seconds,rss_kib" > "$OUT"
end=$(( $(date +%s) + MINUTES * 60 )); start=$(date +%s)
while [ "$(date +%s)" -lt "$end" ]; do
  echo "$(( $(date +%s) - start )),$(awk '/VmRSS/ {print $2}' /proc/$node/status)" >> "$OUT"
  sleep 10
done
kill -INT $sim; wait $sim || true
kill -INT $node; wait $node
tail -n 1 "$OUT.node.err"
INNER
