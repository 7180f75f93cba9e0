#!/usr/bin/env bash
# clearfit's one-command setup for a fresh Debian 12 machine.
#   scripts/bootstrap.sh sample   install dependencies, build (Release), run clearfit assess on the bundled wristband sample
#   scripts/bootstrap.sh test     install dependencies, build (Release), run the whole test suite (ctest)
#   scripts/bootstrap.sh asan     same as test, in a separate AddressSanitizer + UBSan build (build-asan/)
#   scripts/bootstrap.sh fuzz     install dependencies plus clang and libFuzzer's runtime, build every fuzz target (build-fuzz/)
#   scripts/bootstrap.sh sanitize the readers under AddressSanitizer + UBSan (clang, build-sanitize/; CI runs it after test): the fuzz targets
#                                 replay their seeds and regression inputs once, the readers' tests run (docs/fuzzing.md)
#   scripts/bootstrap.sh deps     only install the dependencies
# Idempotent and non-interactive. Needs root or sudo for apt-get.
set -euo pipefail
cd "$(dirname "$0")/.."

PACKAGES=(
  cmake ninja-build g++ pkg-config git
  libeigen3-dev libcgal-dev libopenmesh-dev libtinyobjloader-dev lib3mf-dev libzip-dev libtinygltf-dev
  libembree-dev libtbb-dev libopencv-dev libavformat-dev libavcodec-dev libswscale-dev ffmpeg libapriltag-dev libmrcal-dev mrcal python3-mrcal python3-numpy
  nlohmann-json3-dev libyaml-cpp-dev libcli11-dev libgtest-dev libgmock-dev libbenchmark-dev libssl-dev libboost-dev
  slurm-wlm munge python3-sklearn libgetfem-dev
  chromium
)
# Only for the fuzz build (scripts/fuzz.sh, docs/fuzzing.md): clang, its libFuzzer and sanitizer runtimes.
FUZZ_PACKAGES=(clang libclang-rt-14-dev)

install_deps() {  # install_deps [extra packages...]
  local missing=()
  for p in "${PACKAGES[@]}" "$@"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  if [ ${#missing[@]} -eq 0 ]; then
    echo "== dependencies: all $((${#PACKAGES[@]} + $#)) packages present"
    return
  fi
  echo "== installing ${#missing[@]} missing packages: ${missing[*]}"
  local sudo=""
  [ "$(id -u)" -eq 0 ] || sudo="sudo"
  export DEBIAN_FRONTEND=noninteractive
  $sudo apt-get update -qq
  $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
}

install_web() {  # npm packages for the report viewer and the browser/glTF tests (web/package-lock.json)
  echo "== npm packages (web/package-lock.json)"
  if ! command -v npm > /dev/null; then  # the machine's Node.js normally brings npm; else Debian's
    local sudo=""
    [ "$(id -u)" -eq 0 ] || sudo="sudo"
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq nodejs npm
  fi
  npm ci --prefix web --no-audit --no-fund --loglevel=error
}

build() {  # build DIR [extra cmake args...]
  local dir=$1; shift
  echo "== configuring and building in $dir"
  cmake -S . -B "$dir" -G Ninja -DCMAKE_BUILD_TYPE=Release "$@" > "$dir.configure.log" 2>&1 ||
    { cat "$dir.configure.log"; exit 1; }
  cmake --build "$dir" -j "$(nproc)"
}

run_tests() {  # run_tests DIR
  echo "== running the test suite"
  ctest --test-dir "$1" --output-on-failure -j "$(nproc)" --timeout 600
}

case "${1:-}" in
  deps) install_deps; install_web ;;
  sample)
    install_deps
    install_web
    build build
    cf=./build/cli/clearfit
    s=samples/wristband
    echo "== clearfit simulate: synthetic not-worn and worn captures of a wrist behind the band ($s/captures/)"
    [ -f $s/captures/worn.mkv ] && [ -f $s/captures/presses.csv ] || $cf simulate $s/scene.yaml
    echo "== clearfit calibrate-pressure: the wearer's blanching-to-pressure calibration from the simulated presses"
    $cf calibrate-pressure --presses $s/captures/presses.csv --person wearer-1 --camera $s/camera.cameramodel \
        --out $s/captures/calibration.json --plot $s/captures/calibration.png
    echo "== clearfit assess: where and how hard the band presses"
    $cf assess $s/scene.yaml
    ;;
  test)
    install_deps
    install_web
    build build
    run_tests build
    ;;
  asan)
    install_deps
    install_web
    build build-asan -DCLEARFIT_SANITIZE=ON -DCLEARFIT_BUILD_BENCHMARKS=OFF
    ASAN_OPTIONS=detect_leaks=1 CLEARFIT_RAY_TEST_SCALE=0.1 run_tests build-asan
    ;;
  sanitize)
    install_deps "${FUZZ_PACKAGES[@]}"
    scripts/sanitize-readers.sh
    ;;
  fuzz)
    install_deps "${FUZZ_PACKAGES[@]}"
    echo "== building every fuzz target in build-fuzz/ (scripts/fuzz.sh TARGET SECONDS fuzzes one)"
    FUZZ_BUILD_JOBS=${FUZZ_BUILD_JOBS:-$(nproc)} scripts/fuzz.sh build
    ;;
  *)
    sed -n '2,8p' "$0"
    exit 2
    ;;
esac
