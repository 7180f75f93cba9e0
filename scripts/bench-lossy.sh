#!/usr/bin/env bash
# Lossy phone video (issue 12, item 6): renders the wristband as H.264 (clearfit simulate
# --format h264: libx264, yuv420p, limited range, BT.709) at CRF 18, 23 and 28 and at two
# resolutions, plus the lossless huffyuv capture of the same scene, and assesses each with
# its defaults: false hotspots (places at 4.3 kPa farther than 1 mm from every truth
# hotspot), truth hotspots of 3 mm or more (equivalent diameter at 4.3 kPa) found, their
# centroid errors (the places' centres of pressure against the truth's centroids) and the σ the report gives
# them, and the signal's noise (the spatial term is what compression adds). Usage:
#   scripts/bench-lossy.sh [BUILD_DIR] [SCALES]   (default build, "0.3334 0.5"); work in /tmp/clearfit-lossy
# Environment: SEED (default 31; another seed works in /tmp/clearfit-lossy-seedN), REUSE=1 assesses the
# captures an earlier run rendered there instead of rendering them again (simulate is the slow part).
set -euo pipefail
cd "$(dirname "$0")/.."
cf=$PWD/${1:-build}/cli/clearfit
scales=${2:-0.3334 0.5}
seed=${SEED:-31}
root=/tmp/clearfit-lossy
[ "$seed" = 31 ] || root=/tmp/clearfit-lossy-seed$seed
mkdir -p $root
cd $root
scene() {  # name, scale, format, crf, captures extension
  cat <<YAML
mesh: $OLDPWD/samples/wristband/wristband.obj
contact: {group: contact}
camera: $OLDPWD/samples/wristband/camera.cameramodel
map: {mode: adaptive}
outputs: {folder: $1/out, texel_mm: 0.1}
captures: {baseline: $1/baseline.$5, worn: $1/worn.$5, window_frames: 40}
calibration: {pressure: cal-$2/calibration.json, person: wearer-1}
assess: {smoothing_mm: 0.5}
simulation:
  seed: $seed
  scale: $2
  format: $3
  crf: $4
  timeline: {fps: 30, baseline_s: 2, press_s: 2.5}
  skin: {tone: medium}
  pressure:
    texel_mm: 0.1
    sources:
      - {name: strap-edge, type: gaussian, center_part_mm: [-6, 3, 30], peak_kpa: 14, sigma_mm: 1.6}
      - {name: clasp, type: gaussian, center_part_mm: [6, -3, 30], peak_kpa: 10, sigma_mm: 1.2}
  presses: {diameters_mm: [3], levels: 9, repetitions: 3}
YAML
}
row() {  # name, scale, format, crf, extension
  local name=$1
  scene "$@" > $name.yaml
  if [ "${REUSE:-0}" != 1 ] || [ ! -f $name/truth.json ]; then
    local presses=--no-presses
    [ -f cal-$2/calibration.json ] || presses=
    $cf simulate $name.yaml --out $name --quiet --no-cache $presses > /dev/null
    if [ -z "$presses" ]; then
      mkdir -p cal-$2
      $cf calibrate-pressure --presses $name/presses.csv --person wearer-1 --camera $name/camera.cameramodel --out cal-$2/calibration.json > /dev/null
    fi
  fi
  sed -i "s|^camera: .*|camera: $name/camera.cameramodel|" $name.yaml
  local t0=$(date +%s.%N)
  $cf assess $name.yaml --quiet --no-html > /dev/null
  local t1=$(date +%s.%N)
  /usr/bin/python3 - "$name" "$3" "$4" "$(echo "$t1 - $t0" | bc)" <<'PY'
import json, math, sys
name, fmt, crf, secs = sys.argv[1:5]
r = json.load(open(f"{name}/out/report.json")); t = json.load(open(f"{name}/truth.json"))
v = t["video"]
found_places = [h for h in r["hotspots"] if h["threshold_kpa"] == 4.3]
places = [h["centre_of_pressure_mm"] for h in found_places]
false = sum(min(math.dist(p, h["centroid_part_mm"]) for h in t["hotspots"]) > 1.0 for p in places)
large = [h for h in t["hotspots"] if 2 * math.sqrt(h["area_ge_4_3_kpa_mm2"] / math.pi) >= 3]
# Per truth hotspot: the nearest place's centre error and its reported centre-of-pressure sigma.
nearest = [min(((math.dist(p["centre_of_pressure_mm"], h["centroid_part_mm"]), p.get("centre_of_pressure_sigma_mm")) for p in found_places),
               default=(None, None)) for h in large]
errs = [e for e, _ in nearest]
found = sum(e is not None and e <= 1.0 for e in errs)
sigmas = " / ".join("%.3f" % s if e is not None and e <= 1.0 and s is not None else "-" for e, s in nearest)
size = 0
for f in v["phases"][:1]:
    import os
    size = os.path.getsize(f"{name}/{f['file']}") / 1e3 / f["frames"]
s = r["signal"]
print(f"| {v['width']}x{v['height']} | {fmt} | {crf if fmt == 'h264' else '-'} | {size:.1f} | {false} | {found}/{len(large)} | "
      f"{' / '.join('%.3f' % e if e is not None and e <= 1.0 else 'missed' for e in errs)} | {sigmas} | {s['noise_sigma_temporal']:.5f} | "
      f"{s['noise_sigma_spatial']:.5f} | {float(secs):.1f} |")
PY
}
echo "| resolution | format | CRF | kB/frame | false hotspots | hotspots ≥ 3 mm found | centroid errors (mm) | their σ (mm) | noise σ (frames) | spatial term | assess (s) |"
echo "|---|---|---|---|---|---|---|---|---|---|---|"
for s in $scales; do
  row lossless-$s $s huffyuv 23 mkv
  for crf in 18 23 28; do row h264-$s-$crf $s h264 $crf mp4; done
done
