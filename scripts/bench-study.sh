#!/usr/bin/env bash
# Throughput of clearfit study: trials per minute against --jobs on this machine, memory per
# job, and the projected time of a 100-participant study (8 conditions x 5 trials = 4000
# trials) on a cluster. Renders one wristband trial at the given scale (clearfit simulate),
# lists it N times as distinct trials, and runs `clearfit study run` for each --jobs value.
# Usage: scripts/bench-study.sh [BUILD_DIR] [SCALE] [TRIALS] [JOBS...]
#   (defaults: build 0.5 8 "1 2"); work in /tmp/clearfit-bench-study
set -euo pipefail
cd "$(dirname "$0")/.."
cf=$PWD/${1:-build}/cli/clearfit
scale=${2:-0.5}
trials=${3:-8}
shift $(( $# < 3 ? $# : 3 ))
jobs_list=${*:-1 2}
root=/tmp/clearfit-bench-study
rm -rf $root && mkdir -p $root
s=$PWD/samples/wristband
sed "s|^mesh: .*|mesh: $s/wristband.obj|; s|^camera: .*|camera: $s/camera.cameramodel|; /^outputs:/,/^[a-z]/{/^outputs:/d;/^  /d}" \
  $s/scene.yaml | sed "s|^  out: captures|  out: $root/captures|; s|^  seed: 7|  seed: 7\n  scale: $scale|" > $root/sim.yaml
echo "== rendering one trial at scale $scale"
$cf simulate $root/sim.yaml --quiet > /dev/null
$cf calibrate-pressure --presses $root/captures/presses.csv --person wearer-1 --camera $root/captures/camera.cameramodel \
  --out $root/captures/calibration.json > /dev/null
cat > $root/scene.yaml <<YAML
mesh: $s/wristband.obj
contact: {group: contact}
camera: $root/captures/camera.cameramodel
map: {mode: adaptive}
outputs: {texel_mm: 0.05}
captures: {window_frames: 100}
YAML
{ echo "study: bench"
  echo "participants: [{id: p1, person: wearer-1, calibration: $root/captures/calibration.json}]"
  echo "conditions: [{id: band, scene: $root/scene.yaml}]"
  echo "analysis: {pressure: true}"
  echo "trials:"
  for i in $(seq 1 $trials); do
    echo "  - {id: t$i, participant: p1, condition: band, baseline: $root/captures/baseline.mkv, worn: $root/captures/worn.mkv}"
  done; } > $root/study.yaml
echo "== $(nproc) cores; load average before the runs: $(cut -d' ' -f1-3 /proc/loadavg)"
printf "%-6s %8s %11s %12s %11s %9s\n" jobs wall_s trials_min s_per_trial max_rss_mb load_1min
for j in $jobs_list; do
  rm -rf $root/out-$j
  start=$(date +%s.%N)
  $cf study run $root/study.yaml --out $root/out-$j --jobs $j --quiet > /dev/null
  end=$(date +%s.%N)
  python3 - "$root/out-$j/study.json" "$j" "$start" "$end" "$trials" "$(cut -d' ' -f1 /proc/loadavg)" <<'PY'
import json, sys
s = json.load(open(sys.argv[1])); j = int(sys.argv[2]); wall = float(sys.argv[4]) - float(sys.argv[3]); n = int(sys.argv[5])
load = float(sys.argv[6])
t = [r for r in s["trials"] if r["status"] == "ok"]
per = sum(r["seconds"] for r in t) / len(t); rss = max(r["max_rss_mb"] for r in t)
print(f"{j:<6d} {wall:8.1f} {60 * n / wall:11.2f} {per:12.2f} {rss:11.0f} {load:9.1f}")
open(sys.argv[1] + ".bench", "w").write(json.dumps({"per_trial_s": per, "rss_mb": rss}))
PY
done
python3 - "$root/out-1/study.json.bench" <<'PY'
import json, sys
b = json.load(open(sys.argv[1])); trials = 100 * 8 * 5
for nodes, tasks in ((10, 1), (50, 1), (50, 4)):
    h = trials * b["per_trial_s"] / (nodes * tasks) / 3600
    print(f"projected: 4000 trials (100 participants x 8 conditions x 5 trials) on {nodes} nodes x {tasks} task(s): {h:.2f} h "
          f"(at this machine's {b['per_trial_s']:.1f} s per trial; {b['rss_mb']:.0f} MB per task)")
PY
