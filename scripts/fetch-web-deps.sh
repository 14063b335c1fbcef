#!/usr/bin/env bash
# The JavaScript that xgauge inlines into its HTML reports (src/report/web),
# vendored in third_party/ at a pinned version with its licence: uPlot (MIT)
# from the npm registry. Chosen over Chart.js because every report inlines it:
# 50 kB against about 200 kB, no dependencies, and it draws the thousands of
# points of a fit's loss trace or a calibration table at once; what it lacks
# (error bars) is a few lines of its draw hook. This script checks the vendored files against their pinned
# SHA-256 and, when one is missing or differs, fetches the pinned tarball
# from the npm registry, checks the tarball's sha512 integrity (the value the
# registry publishes) and extracts the files again. Idempotent; called by
# scripts/install-deps.sh. To move to another version, change the three
# pins below together (npm view uplot@X dist.integrity gives the first).
set -euo pipefail
cd "$(dirname "$0")/.."

version=1.6.32
integrity="sha512-KIMVnG68zvu5XXUbC4LQEPnhwOxBuLyW1AHtpm6IKTXImkbLgkMy+jabjLgSLMasNuGGzQm/ep3tOkyTxpiQIw=="
declare -A files=(
  [LICENSE]=8f989229699b4fe2f1a0432d0e9edc338a8a911e250e2d1b01ecd770a5f5b1bd
  [uPlot.iife.min.js]=19c8d4c6ad88929a79f4ae49d6f7161566dfd0ba3d15cc495e974f787eb78f1f
  [uPlot.min.css]=df630c6a8d6f8eeaff264b50f73ce5b114f646ffd9a0bb74f049b0a00135fa04
)
dest=third_party/uplot

check() {
  local name
  for name in "${!files[@]}"; do
    [ -f "$dest/$name" ] || return 1
    echo "${files[$name]}  $dest/$name" | sha256sum --check --status || return 1
  done
}

if check; then
  echo "fetch-web-deps: uPlot $version present and verified"
  exit 0
fi

echo "fetch-web-deps: fetching uPlot $version from the npm registry"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
tarball="$tmp/uplot-$version.tgz"
if command -v npm >/dev/null; then
  (cd "$tmp" && npm pack --silent "uplot@$version" >/dev/null)
else
  curl -fsSL -o "$tarball" "https://registry.npmjs.org/uplot/-/uplot-$version.tgz"
fi
actual="sha512-$(openssl dgst -sha512 -binary "$tarball" | base64 -w0)"
if [ "$actual" != "$integrity" ]; then
  echo "fetch-web-deps: uplot-$version.tgz has integrity $actual, expected $integrity" >&2
  exit 1
fi
tar xzf "$tarball" -C "$tmp" package/LICENSE package/dist/uPlot.iife.min.js package/dist/uPlot.min.css
mkdir -p "$dest"
cp "$tmp/package/LICENSE" "$tmp/package/dist/uPlot.iife.min.js" "$tmp/package/dist/uPlot.min.css" "$dest/"
if ! check; then
  echo "fetch-web-deps: the files extracted from uplot-$version.tgz do not match their pins" >&2
  exit 1
fi
echo "fetch-web-deps: uPlot $version extracted into $dest and verified"
