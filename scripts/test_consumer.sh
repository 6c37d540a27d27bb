#!/usr/bin/env bash
# The C++ package from outside (docs/install.md): builds the tiny consumer project
# tests/consumer/ two ways and runs it.
#   1. find_package(wavebrdf 0.2): against `cmake --install build --prefix <tmp>` of the existing
#      build (BUILD, default build/; not rebuilt), which must be configured and built already.
#      Asking for 0.3, 1.0 or 0.1 instead must fail (0.x: same minor version only). The
#      installed CLI draws a report with the installed Python package (when it was built).
#   2. add_subdirectory(<this source tree>): the consumer's own Debug build of the library, with
#      tests, benchmarks, Python and the CLI off by default (build-consumer/, kept for ccache),
#      compiled with clang where the machine has it (setup.sh installs it): a second compiler for
#      the per-file compile, and at -O0 it takes 0.61 of GCC's CPU (12 of the library's sources:
#      26.2 against 42.7 CPU-s; bench/results/2026-12-02-ci-time.md).
#      Each source file is compiled alone here (no WAVEBRDF_UNITY_BUILD, unlike scripts/setup.sh's
#      and the sanitizer build), so a file that misses an #include fails here.
# Both check that no flag of ours (-march=native, sanitizers, OpenMP, Eigen's path) reaches the
# consumer's compile lines.
# Usage: bash scripts/test_consumer.sh      Environment: BUILD (default build), JOBS (default 2).
set -euo pipefail
cd "$(dirname "$0")/.."
root="$PWD"
build="${BUILD:-build}"
jobs="${JOBS:-2}"
start=$SECONDS

launcher=()
if command -v ccache >/dev/null 2>&1; then
    launcher=(-DCMAKE_C_COMPILER_LAUNCHER=ccache -DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
fi
[ -f "$build/CMakeCache.txt" ] || { echo "test_consumer: $build is not a configured build (run scripts/setup.sh)"; exit 1; }

work="$(mktemp -d "${TMPDIR:-/tmp}/wavebrdf-consumer.XXXXXX")"
trap 'rm -rf "$work"' EXIT

# The consumer's compile lines must carry none of our private flags.
check_flags() {  # build-dir
    local commands="$1/compile_commands.json"
    [ -f "$commands" ] || { echo "test_consumer: no $commands"; exit 1; }
    local leaked
    leaked="$(python3 - "$commands" <<'PY'
import json, sys
bad = ("-march=native", "-fsanitize", "-fopenmp", "eigen3", "EIGEN_")
for entry in json.load(open(sys.argv[1])):
    if "/consumer/" in entry["file"] or entry["file"].endswith("all_headers.cpp"):
        for word in bad:
            if word in entry["command"]:
                print(f"{entry['file']}: {word}")
PY
)"
    if [ -n "$leaked" ]; then
        echo "test_consumer: FAILED: our private flags reach the consumer:"
        echo "$leaked"
        exit 1
    fi
}

echo "test_consumer: 1. find_package against an install of $build"
cmake --install "$build" --prefix "$work/prefix" >"$work/install.log"
cmake -S tests/consumer -B "$work/installed" -DCMAKE_PREFIX_PATH="$work/prefix" \
    -DCMAKE_BUILD_TYPE=Release -DCMAKE_EXPORT_COMPILE_COMMANDS=ON "${launcher[@]}" >"$work/configure.log"
cmake --build "$work/installed" -j"$jobs" >"$work/build.log" || { cat "$work/build.log"; exit 1; }
check_flags "$work/installed"
"$work/installed/wavebrdf_consumer" "$work"
for version in 0.3 1.0 0.1; do
    if cmake -S tests/consumer -B "$work/v$version" -DCMAKE_PREFIX_PATH="$work/prefix" \
            -DCONSUMER_WAVEBRDF_VERSION="$version" >"$work/v$version.log" 2>&1; then
        echo "test_consumer: FAILED: find_package(wavebrdf $version) found $(cat VERSION)"
        exit 1
    fi
    grep -q "compatible with requested version \"$version\"" "$work/v$version.log" || { cat "$work/v$version.log"; exit 1; }
done
echo "test_consumer: find_package(wavebrdf 0.3 / 1.0 / 0.1) refused, as they should be"

# The installed CLI: its version, and a report drawn with the installed package from another
# directory, without PYTHONPATH (when the build has the Python module and matplotlib is there).
"$work/prefix/bin/wavebrdf" --version
if [ -n "$(find "$work/prefix" -path '*/wavebrdf/python/wavebrdf/report.py')" ] &&
        /usr/bin/python3 -c 'import numpy, matplotlib' 2>/dev/null; then
    mkdir -p "$work/run"
    (cd "$work/run" && env -u PYTHONPATH "$work/prefix/bin/wavebrdf" recover --size 8 --texel-um 2 --sigma-p-um 3 \
        --height-range-um 0.1 --seed 3 --method thesis --epochs 2 --quiet --out rec 2>"$work/report.err")
    # Two epochs do not converge, and the run says so in one line: any other line is a failure.
    grep -v '^wavebrdf: warning: the recovery did not converge' "$work/report.err" >"$work/report.other" || true
    if [ -s "$work/report.other" ] || [ ! -s "$work/run/rec/report.png" ]; then
        cat "$work/report.err"
        echo "test_consumer: FAILED: the installed CLI did not draw report.png"
        exit 1
    fi
    echo "test_consumer: the installed CLI drew report.png with the installed package"
else
    echo "test_consumer: no installed Python package or no matplotlib: report not checked"
fi

# A Debug consumer: a second build type, and -O0 compiles the whole library (this part builds
# all of it, with the consumer's flags) faster than -O2.
compilers=()
if command -v clang >/dev/null 2>&1 && command -v clang++ >/dev/null 2>&1; then
    compilers=(-DCMAKE_C_COMPILER=clang -DCMAKE_CXX_COMPILER=clang++)
fi
echo "test_consumer: 2. add_subdirectory of the source tree (Debug${compilers:+, clang})"
cmake -S tests/consumer -B build-consumer -DWAVEBRDF_SOURCE_DIR="$root" -DCMAKE_BUILD_TYPE=Debug \
    -DCMAKE_EXPORT_COMPILE_COMMANDS=ON "${compilers[@]}" "${launcher[@]}" >"$work/sub-configure.log"
cache=build-consumer/CMakeCache.txt
for option in WAVEBRDF_BUILD_TESTS WAVEBRDF_BUILD_BENCH WAVEBRDF_BUILD_PYTHON WAVEBRDF_BUILD_CLI \
        WAVEBRDF_BUILD_EXPERIMENTS WAVEBRDF_NATIVE; do
    grep -q "^$option:BOOL=OFF$" "$cache" || { echo "test_consumer: FAILED: $option is not OFF for a consumer"; exit 1; }
done
cmake --build build-consumer -j"$jobs" >"$work/sub-build.log" || { cat "$work/sub-build.log"; exit 1; }
check_flags build-consumer
build-consumer/wavebrdf_consumer "$work"
echo "test_consumer: passed in $((SECONDS - start)) s"
