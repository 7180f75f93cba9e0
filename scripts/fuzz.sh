#!/usr/bin/env bash
# Fuzz clearfit's readers with libFuzzer (clang, AddressSanitizer, UBSan).
#   scripts/fuzz.sh                 list the targets
#   scripts/fuzz.sh TARGET [SECONDS] build fuzz_TARGET in build-fuzz/ and fuzz it for SECONDS (default 60)
#   scripts/fuzz.sh all [SECONDS]    every target in turn, SECONDS each
#   scripts/fuzz.sh build            only build every fuzz target (what `scripts/bootstrap.sh fuzz` runs)
# FUZZ_NO_BUILD=1 skips the build step (fuzz with the binary in build-fuzz/ as it is,
# e.g. while build-fuzz/ is being built for another target); FUZZ_BUILD_JOBS sets -j (2).
# Before fuzzing, every input kept in fuzz/regressions/TARGET/ (past crashers)
# is run once: a regression fails the script. The working corpus grows in
# build-fuzz/corpus/TARGET (seeded from fuzz/seeds/TARGET); a crasher is
# written to build-fuzz/crashes/TARGET/ — fix it, then keep it in
# fuzz/regressions/TARGET/. One fuzzer process at a time (-jobs/-workers 1).
# Needs: clang, libclang-rt-14-dev (apt) and the packages of scripts/bootstrap.sh:
# `scripts/bootstrap.sh fuzz` installs them all.
set -euo pipefail
cd "$(dirname "$0")/.."
TARGETS=(stl obj ply off 3mf gltf glb scene config cameramodel pose board tag_layout corners calibration presses force_log manifest)
if [ $# -eq 0 ]; then
  echo "targets: ${TARGETS[*]}"
  exit 0
fi
target=$1
seconds=${2:-60}
build=build-fuzz
configure() {
  command -v clang++ > /dev/null ||
    { echo "clang++ not found: the fuzz build needs clang and libFuzzer; run scripts/bootstrap.sh fuzz (installs clang and libclang-rt-14-dev)" >&2; exit 2; }
  [ -f "$(clang++ -print-runtime-dir)/libclang_rt.fuzzer-x86_64.a" ] ||
    { echo "libFuzzer's runtime is missing from $(clang++ -print-runtime-dir): run scripts/bootstrap.sh fuzz (installs libclang-rt-14-dev)" >&2; exit 2; }
  if [ ! -f $build/build.ninja ]; then
    cmake -S . -B $build -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_COMPILER=clang++ -DCLEARFIT_FUZZ=ON \
      -DCLEARFIT_BUILD_TESTS=OFF -DCLEARFIT_BUILD_BENCHMARKS=OFF > $build.configure.log
  fi
}
if [ "$target" = build ]; then
  configure
  cmake --build $build -j"${FUZZ_BUILD_JOBS:-2}" --target "${TARGETS[@]/#/fuzz_}"
  exit 0
fi
if [ "$target" = all ]; then
  for t in "${TARGETS[@]}"; do "$0" "$t" "$seconds"; done
  exit 0
fi
printf '%s\n' "${TARGETS[@]}" | grep -qx "$target" || { echo "unknown target '$target' (targets: ${TARGETS[*]})" >&2; exit 2; }
exe=$build/fuzz/fuzz_$target
if [ "${FUZZ_NO_BUILD:-0}" = 1 ]; then
  [ -x "$exe" ] || { echo "$exe is not built (FUZZ_NO_BUILD=1): run scripts/fuzz.sh build" >&2; exit 2; }
else
  configure
  cmake --build $build -j"${FUZZ_BUILD_JOBS:-2}" --target "fuzz_$target"
fi
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
if [ -d fuzz/regressions/$target ] && [ -n "$(ls -A fuzz/regressions/$target)" ]; then
  echo "== fuzz_$target: $(ls fuzz/regressions/$target | wc -l) regression inputs"
  "$exe" -runs=0 fuzz/regressions/$target/* 2>&1 | tail -2
fi
mkdir -p $build/corpus/$target $build/crashes/$target
seeds=()
[ -d fuzz/seeds/$target ] && seeds+=(fuzz/seeds/$target)
# lib3mf leaks inside libzip on every 3MF it reads (suppressed in fuzz_geometry.cpp), so
# libFuzzer's per-input leak check would run LeakSanitizer after every input (3x slower);
# leaks are still checked once at exit.
extra=()
[ "$target" = 3mf ] && extra+=(-detect_leaks=0)
echo "== fuzz_$target for $seconds s"
"$exe" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -max_len=65536 -print_final_stats=1 "${extra[@]}" \
  -artifact_prefix=$build/crashes/$target/ $build/corpus/$target "${seeds[@]}" 2>&1 | tee $build/fuzz_$target.log | grep -E "^(#[0-9]+ *DONE|stat::|==[0-9]+==ERROR|SUMMARY|Done)" || true
grep -q "ERROR\|SUMMARY:\|deadly signal" $build/fuzz_$target.log && { echo "fuzz_$target: FOUND A CRASH (see $build/fuzz_$target.log, $build/crashes/$target/)"; exit 1; }
exit 0
