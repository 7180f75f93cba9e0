#!/usr/bin/env bash
# Glare and exposure / white balance / flicker (issue 12, items 4 and 5): renders the
# wristband at quarter resolution with each effect at several strengths (clearfit
# simulate), and assesses each with the corrections on and off: false hotspots (places
# at 4.3 kPa farther than 1 mm from every truth hotspot), centroid errors, pressure
# RMSE against the truth, the signal's noise estimate, the masked area and the run time. Usage:
#   scripts/bench-photometric.sh [BUILD_DIR]     (default build); work in /tmp/clearfit-photometric
set -euo pipefail
cd "$(dirname "$0")/.."
cf=$PWD/${1:-build}/cli/clearfit
root=/tmp/clearfit-photometric
mkdir -p $root
cd $root
scene() {  # name, effects (YAML lines under simulation:)
  cat <<YAML
mesh: $OLDPWD/samples/wristband/wristband.obj
contact: {group: contact}
camera: $OLDPWD/samples/wristband/camera.cameramodel
map: {mode: adaptive}
outputs: {folder: $1/out, texel_mm: 0.1}
captures: {baseline: $1/baseline.mkv, worn: $1/worn.mkv, window_frames: 40}
calibration: {pressure: clean/calibration.json, person: wearer-1}
assess: {smoothing_mm: 0.5}
simulation:
  seed: 31
  scale: 0.25
  timeline: {fps: 30, baseline_s: 2, press_s: 2.5}
  skin: {tone: medium}
  pressure:
    texel_mm: 0.1
    sources:
      - {name: strap-edge, type: gaussian, center_part_mm: [-6, 3, 30], peak_kpa: 14, sigma_mm: 1.6}
      - {name: clasp, type: gaussian, center_part_mm: [6, -3, 30], peak_kpa: 10, sigma_mm: 1.2}
  presses: {diameters_mm: [3], levels: 9, repetitions: 3}
$2
YAML
}
render() {  # name, effects
  scene "$1" "$2" > $1.yaml
  $cf simulate $1.yaml --out $1 --quiet --no-cache $3 > /dev/null
  sed -i "s|^camera: .*|camera: clean/camera.cameramodel|" $1.yaml
}
render clean "" ""
$cf calibrate-pressure --presses clean/presses.csv --person wearer-1 --camera clean/camera.cameramodel --out clean/calibration.json > /dev/null
row() {  # name, strength, correction flag(s)
  local name=$1 strength=$2 on=$3; shift 3
  local t0=$(date +%s.%N)
  $cf assess $name.yaml --quiet --no-html "$@" > /dev/null
  local t1=$(date +%s.%N)
  $cf bench assess $name.yaml --json $name/bench.json "$@" > /dev/null
  python3 - "$name" "$strength" "$on" "$(echo "$t1 - $t0" | bc)" <<'PY'
import json, math, sys
name, strength, on, secs = sys.argv[1:5]
r = json.load(open(f"{name}/out/report.json")); b = json.load(open(f"{name}/bench.json"))["accuracy"]
t = json.load(open(f"{name}/truth.json"))["hotspots"]
places = [h["centre_of_pressure_mm"] for h in r["hotspots"]]
false = sum(min(math.dist(p, h["centroid_part_mm"]) for h in t) > 1.0 for p in places)
err = [h["centroid_error_mm"] for h in b["hotspots"]]
print(f"| {name.split('-')[0]} | {strength} | {on} | {false} | {' / '.join('%.3f' % e if e is not None else 'missed' for e in err)} | "
      f"{b['rmse_kpa']:.2f} | {r['signal']['noise_sigma']:.5f} | {r['coverage'].get('glare_masked_mm2', 0):.0f} | {float(secs):.1f} |")
PY
}
echo "| effect | strength | corrections | false hotspots | centroid errors (mm) | RMSE (kPa) | signal noise σ | glare masked (mm²) | assess (s) |"
echo "|---|---|---|---|---|---|---|---|---|"
row clean - on
for peak in 0.05 0.15 0.4; do
  render glare-$peak "  glare:
    - {center: [0.34, 0.62], sigma: 0.025, peak: $peak, phases: both}
    - {center: [0.68, 0.4], sigma: 0.03, peak: $peak, phases: worn}" --no-presses
  row glare-$peak "peak $peak" on
  row glare-$peak "peak $peak" off --no-glare-mask
done
for step in 0.02 0.05 0.10; do
  up=$(echo "1 + $step" | bc) down=$(echo "1 - $step" | bc)
  render gains-$step "  exposure:
    steps: [{t_s: 1.0, gain: [$up, $up, $up]}, {t_s: 2.3, gain: [$down, 1.0, $up]}, {t_s: 3.6, gain: $down}]
    drift_per_s: [0.01, -0.01, 0.005]
  flicker: {amplitude: $step, hz: 100, drift_hz_per_s: 0.3}" --no-presses
  row gains-$step "steps ±$step" on
  row gains-$step "steps ±$step" off --no-exposure-normalisation
done
