#!/usr/bin/env bash
# The readers under AddressSanitizer and UndefinedBehaviorSanitizer, as a second build: CI's
# second stage (.ci/run; docs/fuzzing.md, "The readers under the sanitizers", has its figures).
# One clang build in build-sanitize/ with the fuzz build's flags (-O2 -g, ASan, UBSan,
# -fno-sanitize-recover): the fuzz targets of every reader, the scene's and the --config file's
# included (their readers compile the simulator and the refraction map: 43 more steps, about 345 CPU-s
# cold; built here so that their source lists cannot stop linking unseen), and the test programs of
# the readers: core/format, geometry/import, camera/camera_model, camera/board and camera/pose.
# Then every fuzz target replays its seeds and its kept regression inputs once (libFuzzer
# -runs=0: no mutation, the same inputs every run), and the test programs run.
# The whole suite under the sanitizers is `scripts/bootstrap.sh asan` (by hand: too long for CI).
# Needs clang and libclang-rt-14-dev: `scripts/bootstrap.sh sanitize` installs them.
#   scripts/sanitize-readers.sh [BUILD_DIR]     default build-sanitize; SANITIZE_JOBS sets -j (nproc)
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build-sanitize}
jobs=${SANITIZE_JOBS:-$(nproc)}
command -v clang++ > /dev/null || { echo "clang++ not found: run scripts/bootstrap.sh sanitize" >&2; exit 2; }
if [ ! -f "$build/build.ninja" ]; then
  echo "== configuring $build (clang, AddressSanitizer + UBSan)"
  cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_COMPILER=clang++ -DCLEARFIT_FUZZ=ON \
    -DCLEARFIT_BUILD_TESTS=ON -DCLEARFIT_BUILD_BENCHMARKS=OFF > "$build.configure.log" 2>&1 ||
    { cat "$build.configure.log"; exit 1; }
fi
targets=$(sed -n 's/^TARGETS=(\(.*\))$/\1/p' scripts/fuzz.sh)
tests=(test_core_format_test test_geometry_import_test test_camera_camera_model_test test_camera_board_test test_camera_pose_test)
echo "== building $(echo $targets | wc -w) fuzz targets and ${#tests[@]} test programs in $build"
cmake --build "$build" -j"$jobs" --target $(printf 'fuzz_%s ' $targets) "${tests[@]}"
export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
status=0
for t in $targets; do
  inputs=(fuzz/seeds/$t)
  [ -d fuzz/regressions/$t ] && inputs+=(fuzz/regressions/$t)
  extra=()
  [ "$t" = 3mf ] && extra+=(-detect_leaks=0)  # lib3mf leaks in libzip (fuzz/fuzz_geometry.cpp); checked at exit
  files=$(find "${inputs[@]}" -type f | wc -l)
  if "$build/fuzz/fuzz_$t" -runs=0 -timeout=10 -rss_limit_mb=2048 "${extra[@]}" "${inputs[@]}" > "$build/replay_$t.log" 2>&1 &&
     ! grep -q "ERROR: \|SUMMARY: \|deadly signal" "$build/replay_$t.log"; then
    echo "fuzz_$t: $files inputs replayed, clean"
  else
    echo "fuzz_$t: FAILED on its seeds or regression inputs ($build/replay_$t.log):"
    tail -30 "$build/replay_$t.log"
    status=1
  fi
done
echo "== the readers' tests under the sanitizers"
passed=0 failed=0
for t in "${tests[@]}"; do
  if "$build/tests/$t" --gtest_brief=1 > "$build/$t.log" 2>&1; then
    passed=$((passed + 1))
  else
    failed=$((failed + 1)) status=1
    echo "$t FAILED ($build/$t.log):"
    tail -30 "$build/$t.log"
  fi
done
echo "$passed passed, $failed failed"
exit $status
