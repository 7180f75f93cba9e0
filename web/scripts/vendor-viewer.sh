#!/usr/bin/env bash
# Vendors report.html's 3D viewer, reproducibly: installs web/ from its lockfile
# (npm ci, only when node_modules lacks the package) and copies @google/model-viewer's
# UMD bundle (a classic script with three.js inside, so it runs from file:// with no
# module loading) and the licences into reports/assets/vendor/, where the report
# generator reads it (see docs: reports/assets/README.md).
#   web/scripts/vendor-viewer.sh           write reports/assets/vendor/
#   web/scripts/vendor-viewer.sh --check   exit 1 when the vendored copy differs from the lockfile's
set -euo pipefail
cd "$(dirname "$0")/.."
src=node_modules/@google/model-viewer
[ -f "$src/package.json" ] || npm ci --no-audit --no-fund
version=$(node -p "require('./$src/package.json').version")
three=$(node -p "require('./node_modules/three/package.json').version")
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
{
  echo "/* @google/model-viewer $version (Apache-2.0) with three.js $three (MIT): dist/model-viewer-umd.min.js,"
  echo "   vendored by web/scripts/vendor-viewer.sh from web/package-lock.json; licences beside this file. */"
  sed '/^\/\/# sourceMappingURL=/d' "$src/dist/model-viewer-umd.min.js"
} > "$out/model-viewer-umd.min.js"
cp "$src/LICENSE" "$out/model-viewer.LICENSE"
cp node_modules/three/LICENSE "$out/three.LICENSE"
dst=../reports/assets/vendor
if [ "${1:-}" = "--check" ]; then
  diff -rq "$out" "$dst" && echo "vendored viewer matches model-viewer $version / three $three"
  exit
fi
mkdir -p "$dst"
cp "$out"/* "$dst"/
echo "vendored model-viewer $version (three $three) into reports/assets/vendor/"
