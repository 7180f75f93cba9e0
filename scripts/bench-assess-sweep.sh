#!/usr/bin/env bash
# Accuracy of clearfit assess across skin tones, noise and motion: renders variants of the
# wristband sample at half resolution (clearfit simulate), calibrates each simulated wearer
# from its presses and runs clearfit-bench assess against the truth. Usage:
#   scripts/bench-assess-sweep.sh [BUILD_DIR]     (default build); work in /tmp/clearfit-sweep
set -euo pipefail
cd "$(dirname "$0")/.."
cf=${1:-build}/cli/clearfit
cfb=${1:-build}/bench/clearfit-bench
root=/tmp/clearfit-sweep
mkdir -p $root
base=$(sed '/^simulation:/,$d' samples/wristband/scene.yaml | grep -v '^captures:\|^  baseline:\|^  worn:\|^  window_frames:\|^calibration:\|^  pressure:\|^  person:' )
for variant in "medium 0 3" "light 0 3" "dark 0 3" "medium 0.1 3" "medium 0 12"; do
  set -- $variant
  tone=$1 motion=$2 read_noise=$3
  name=$tone-motion$motion-noise$read_noise
  dir=$root/$name
  mkdir -p $dir
  { echo "$base" | sed "s|^mesh: .*|mesh: $PWD/samples/wristband/wristband.obj|; s|^camera: .*|camera: $dir/captures/camera.cameramodel|"
    cat <<YAML
captures: {baseline: captures/baseline.mkv, worn: captures/worn.mkv, window_frames: 100}
calibration: {pressure: captures/calibration.json, person: wearer-1}
simulation:
  seed: 7
  out: captures
  scale: 0.5
  timeline: {fps: 60, baseline_s: 2, press_s: 3}
  skin: {tone: $tone}
  camera: {read_noise_e: $read_noise}
  motion: {step_px: $motion}
  pressure:
    texel_mm: 0.05
    sources:
      - {name: strap-edge, type: gaussian, center_part_mm: [-6, 3, 30], peak_kpa: 14, sigma_mm: 1.6}
      - {name: clasp, type: gaussian, center_part_mm: [6, -3, 30], peak_kpa: 10, sigma_mm: 1.2}
  presses: {diameters_mm: [3, 5], levels: 9, repetitions: 3}
YAML
  } > $dir/scene.yaml
  sed -i "s|^camera: .*|camera: $PWD/samples/wristband/camera.cameramodel|" $dir/scene.yaml
  $cf simulate $dir/scene.yaml --quiet > /dev/null
  sed -i "s|^camera: .*|camera: captures/camera.cameramodel|" $dir/scene.yaml
  $cf calibrate-pressure --presses $dir/captures/presses.csv --person wearer-1 --camera $dir/captures/camera.cameramodel \
      --out $dir/captures/calibration.json > /dev/null
  echo "== $name"
  $cfb assess $dir/scene.yaml | grep -E "RMSE|sensitivity|centroid"
done
