#!/usr/bin/env bash
# Installs every build, test and benchmark dependency of xgauge from Debian's
# packages (Debian 12). Used by .ci/run and the README. Idempotent.
set -euo pipefail

packages=(
  build-essential cmake ninja-build pkg-config git
  libeigen3-dev        # vectors, transforms, small linear algebra
  libboost-dev         # Boost.Math (header-only): Student's t, normal and chi-square quantiles
  libtbb-dev           # oneTBB: parallel loops
  libtiff-dev          # TIFF read/write
  libhdf5-dev          # NeXus NXtomo radiographs (libhdf5's C API)
  libdcmtk-dev         # DICONDE (DICOM) radiographs
  libxrl-dev           # xraylib: attenuation data
  libnlopt-cxx-dev     # NLopt with the C++ interface
  libceres-dev         # Ceres Solver: the final least-squares stage and its covariance
  nlohmann-json3-dev   # JSON
  libmuparser-dev      # dimension expressions in part models
  libocct-foundation-dev libocct-modeling-data-dev libocct-modeling-algorithms-dev
  libocct-data-exchange-dev libocct-ocaf-dev libocct-visualization-dev
                       # OpenCASCADE: "step" shapes (read, check, tessellate STEP
                       # solids); its CMake package needs the last two's targets
  occt-misc            # OpenCASCADE's sample CAD files: screw.step, the part of
                       # examples/screw/ and of the STEP tests
  libssl-dev           # SHA-256 of input files (libcrypto)
  libcli11-dev         # command line parsing
  libfmt-dev libspdlog-dev
  libstb-dev           # PNG previews (stb_image_write)
  libsqlite3-dev       # the results store (src/production), SQLite by default
  libpqxx-dev          # ... and PostgreSQL for several stations
  postgresql           # CTest starts a throw-away server for the PostgreSQL store's tests
  slurm-wlm            # bench/production/slurm_array.sh: a throw-away one-node Slurm runs the docs' job array
  python3-kubernetes   # bench/production/k8s_manifest.py: the docs' Kubernetes Job against the API schema
  libgtest-dev libgmock-dev libbenchmark-dev
  pybind11-dev python3-dev   # the Python module xgauge (python/, docs/python.md)
  python3-jsonschema   # tests/validate_schemas.py: JSON files against docs/schemas
  python3-numpy python3-scipy python3-xraylib python3-tifffile python3-pytest
                       # tools/lab2: the second, independent virtual lab and its tests
  clang-format clang-tidy   # scripts/tidy.sh
  clang libclang-rt-14-dev llvm   # scripts/fuzz.sh: libFuzzer, sanitizers, symbolizer
  chromium fonts-dejavu-core   # tests/report_test.py: the HTML reports in headless Chromium
  curl ca-certificates openssl # scripts/fetch-web-deps.sh (uPlot, when not vendored already)
)

sudo_cmd=()
if [ "$(id -u)" -ne 0 ]; then sudo_cmd=(sudo); fi

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#packages[@]} packages already installed"
else
  echo "install-deps: installing ${missing[*]}"
  export DEBIAN_FRONTEND=noninteractive
  "${sudo_cmd[@]}" apt-get update -qq
  "${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

# The chart library the HTML reports inline (npm registry, pinned, hash-checked).
bash "$(dirname "$0")/fetch-web-deps.sh"
