#!/usr/bin/env bash
# Installs what wavebrdf needs (Debian packages) and builds it into build/ (Release).
# Usage: bash scripts/setup.sh [--demo] [extra cmake args...]
# --demo: only what scripts/demo.sh needs: its packages (those of the CLI and the Python module)
# and ccache, and only the CLI built (demo.sh builds the module itself, after its first pictures);
# not the tests, benchmarks, MPI, HDF5, clang or the documentation tools.
set -euo pipefail
cd "$(dirname "$0")/.."

demo=0
[ "${1:-}" = --demo ] && { demo=1; shift; }
# The demo's packages (what the library, the CLI and the Python module need), then the rest.
packages=(build-essential cmake pkg-config ccache libopenexr-dev libeigen3-dev libcli11-dev
          nlohmann-json3-dev libfftw3-dev libpng-dev python3 python3-numpy python3-matplotlib
          python3-dev pybind11-dev
          python3-munkres  # fonttools (matplotlib) needs SciPy or this: named, SciPy, Pythran and Boost stay out (300 MB)
          libzip-dev libpugixml-dev)  # x3p surface files (docs/surfaces.md)
[ "$demo" = 1 ] || packages+=(libgtest-dev libbenchmark-dev
          python3-pil python3-pytest python3-torch
          python3-scipy python3-cvxopt python3-h5py  # independent checks in the Python tests (HiGHS, a semidefinite solver, HDF5 files)
          python3-venv python3-setuptools python3-pip python3-wheel python3-tqdm doxygen
          libopenmpi-dev openmpi-bin python3-mpi4py libhdf5-dev  # MPI and HDF5 (docs/scale.md)
          gwyddion libgwyddion20-dev libgtk2.0-dev libgtkglext1-dev  # tests/gwyddion/gwy_probe.c (gwyddion.pc needs GTK 2)
          clang libclang-rt-dev libomp-dev)  # clang: the fuzzers (scripts/fuzz.sh)
missing=()
for p in "${packages[@]}"; do
    dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
    echo "setup: installing ${missing[*]}"
    SUDO=""
    [ "$(id -u)" -ne 0 ] && SUDO="sudo"
    $SUDO apt-get update -qq
    # The demo installs no recommended packages: it needs none, and on a new machine unpacking is
    # most of its set-up time.
    lean=()
    [ "$demo" = 1 ] && lean=(--no-install-recommends)
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${lean[@]}" "${missing[@]}" >/dev/null
fi

# ccache, where the machine has it, makes rebuilds of other checkouts nearly free.
launcher=()
command -v ccache >/dev/null 2>&1 && launcher=(-DCMAKE_C_COMPILER_LAUNCHER=ccache -DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
# WAVEBRDF_UNITY_BUILD: the library, the CLI, the Python module and the tests compiled in batches, so that a
# fresh build parses the headers once a batch instead of once a file (CMakeLists.txt).
if [ "$demo" = 1 ]; then
    cmake -S . -B build -DCMAKE_BUILD_TYPE=Release -DWAVEBRDF_BUILD_TESTS=OFF -DWAVEBRDF_BUILD_BENCH=OFF \
          -DWAVEBRDF_BUILD_EXPERIMENTS=OFF -DWAVEBRDF_UNITY_BUILD=ON "${launcher[@]}" "$@" >/dev/null
    cmake --build build -j"$(nproc)" --target wavebrdf_cli
else
    # Explicit: a build/ configured by --demo has the tests, benchmarks and experiments cached OFF.
    cmake -S . -B build -DCMAKE_BUILD_TYPE=Release -DWAVEBRDF_BUILD_TESTS=ON -DWAVEBRDF_BUILD_BENCH=ON \
          -DWAVEBRDF_BUILD_EXPERIMENTS=ON -DWAVEBRDF_UNITY_BUILD=ON "${launcher[@]}" "$@" >/dev/null
    cmake --build build -j"$(nproc)"
fi
