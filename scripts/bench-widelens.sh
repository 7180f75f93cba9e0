#!/bin/bash
# A 112-degree lens calibrated from rendered AprilTag boards that do not reach
# the image corners (issue 15 §6): clearfit calibrate (images: detection,
# lens-aware refinement, second solve), the same with --mrcal-regularization
# (mrcal's regularisation sized for 1 px corners, as before), and
# mrcal-calibrate-cameras on clearfit detect's corners.vnl. Each model's
# projection against the true lens over a 64 x 48 grid (camera rotation fitted
# over the cells with corners): p50 / p95 / max over the whole image, the
# cells with corners and the others.
#   scripts/bench-widelens.sh BUILD_DIR [seeds="4 5 6 7"] [out=/tmp/clearfit-widelens] [uncertainty]
# With `uncertainty`, clearfit's model carries its projection uncertainty map (the calibration takes longer)
# and the score's second line sets it beside the error: sigma and the error at the image corners.
# (build first: cmake --build BUILD_DIR --target clearfit widelens_bench; needs -DCLEARFIT_BUILD_BENCHMARKS=ON)
# The lens: an equidistant fisheye (r = f theta, f 655 px) as OPENCV8 (bench/widelens_bench.cpp);
# 30 views, boards centred anywhere, 350-900 mm, at least 60 % of their corners in the image and none beyond
# 85 % of the half diagonal; views with under 60 detected corners (a few far, small tags) are left out of
# corners.vnl for mrcal's tool. About 1.5 min per seed on 2 cores.
set -u
build=$(realpath "${1:?usage: scripts/bench-widelens.sh BUILD_DIR [seeds] [out]}")
seeds=${2:-"4 5 6 7"}
out=${3:-/tmp/clearfit-widelens}
uncertainty=--no-uncertainty
[ "${4:-}" = uncertainty ] && uncertainty=
bench=$build/bench/widelens_bench
cf=$build/cli/clearfit
for s in $seeds; do
  d=$out/seed$s
  rm -rf "$d"
  "$bench" render "$d" "$s" 30 1.1 350 900 0.85 > /dev/null || exit 2
  cd "$d" || exit 2
  "$cf" detect --board board.yaml images --out raw.vnl --quiet > /dev/null 2>&1 || exit 2
  awk 'NR==FNR{if(FNR>1 && $2!="-") n[$1]++; next} FNR==1{print; next}
       {if(n[$1]+0>=60) print; else if(!s[$1]++) print $1" - - -"}' raw.vnl raw.vnl > corners.vnl
  "$cf" calibrate --board board.yaml images --out clearfit.cameramodel $uncertainty > clearfit.log 2>&1
  "$cf" calibrate --board board.yaml images --out mrcal-sized.cameramodel --no-uncertainty \
    --mrcal-regularization > mrcal-sized.log 2>&1
  mkdir -p mrcal
  /usr/bin/mrcal-calibrate-cameras --corners-cache corners.vnl --corners-cache-has-weights \
    --lensmodel LENSMODEL_OPENCV8 --focal 650 --imagersize 1280 960 --object-spacing 30 \
    --object-width-n 16 --object-height-n 12 --outdir mrcal 'images/*.png' > mrcal.log 2>&1
  echo "seed $s"
  for m in clearfit.cameramodel mrcal-sized.cameramodel mrcal/camera-0.cameramodel; do
    if [ -f "$m" ]; then
      "$bench" score truth.cameramodel "$m" corners.vnl 1280 960 16 12 30
    else
      echo "$m: not written ($(grep -m1 -o 'Exception: .*' mrcal.log))"
    fi
  done
  cd - > /dev/null || exit 2
done
