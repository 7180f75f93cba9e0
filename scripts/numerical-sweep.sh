#!/usr/bin/env bash
# The numerical-limits sweep at full size (issue 16, section 5; README "Reliability"):
# the suite's numerical-limits tests and the ray stress tests with CLEARFIT_RAY_TEST_SCALE
# raised, so that the random-pose map sweep traces millions of pixels over thousands of
# poses and the ray stress test a million rays and more. The suite runs them at scale 1
# (a few seconds); this takes minutes.
#   scripts/numerical-sweep.sh [BUILD_DIR] [SCALE]     defaults: build 10
# Prints each test's summary lines (counts per outcome, worst errors) and its wall time;
# exits non-zero when any of them fails.
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
scale=${2:-10}
tests=(
  "refraction numerical_limits_test"
  "refraction map_properties_test"
  "geometry ray_index_test"
  "camera numerical_limits_test"
  "fit numerical_limits_test"
)
cmake --build "$build" -j"${SWEEP_BUILD_JOBS:-2}" --target $(for t in "${tests[@]}"; do set -- $t; echo "test_$1_$2"; done)
status=0
for t in "${tests[@]}"; do
  set -- $t
  exe=$build/tests/test_$1_$2
  echo "== $1/$2 at CLEARFIT_RAY_TEST_SCALE=$scale"
  start=$(date +%s%N)
  if CLEARFIT_RAY_TEST_SCALE=$scale "$exe" --gtest_brief=1 > "$build/numerical-sweep-$1-$2.log" 2>&1; then result=passed; else result=FAILED; status=1; fi
  grep -E "^  |FAILED|Failure" "$build/numerical-sweep-$1-$2.log" | head -60 || true
  ms=$((($(date +%s%N) - start) / 1000000))
  printf '%s/%s: %s in %d.%03d s (log: %s)\n' "$1" "$2" "$result" $((ms / 1000)) $((ms % 1000)) "$build/numerical-sweep-$1-$2.log"
done
exit $status
