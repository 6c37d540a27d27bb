#!/usr/bin/env bash
# Sets up, builds and runs every test: the Release build, then the same suite built with
# AddressSanitizer and UndefinedBehaviorSanitizer, then the fuzzers (scripts/fuzz.sh, FUZZ_SECONDS
# each, default 60).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh -DWAVEBRDF_BUILD_PYTHON=ON  # explicit: an older build/ may have it cached OFF
(cd build && ctest --output-on-failure -j"$(nproc)")
echo "test: Python (pytest)"
/usr/bin/python3 -m pytest -q tests/python
bash scripts/docs.sh  # the API reference (Doxygen + pydoc) builds without warnings
JOBS="$(nproc)" bash scripts/test_consumer.sh  # the C++ package: find_package against an install, and add_subdirectory
bash scripts/test_pip.sh  # pip install in a fresh venv, smoke test outside the tree

echo "test: sanitizer build (ASan + UBSan)"
launcher=()  # ccache, where the machine has it, as in setup.sh (a fresh CI machine has none)
command -v ccache >/dev/null 2>&1 && launcher=(-DCMAKE_C_COMPILER_LAUNCHER=ccache -DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
cmake -S . -B build-sanitize -DCMAKE_BUILD_TYPE=RelWithDebInfo -DWAVEBRDF_SANITIZE=ON \
      -DWAVEBRDF_BUILD_BENCH=OFF -DWAVEBRDF_BUILD_PYTHON=OFF "${launcher[@]}" >/dev/null
cmake --build build-sanitize -j"$(nproc)"
export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1
export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
# The slowest recoveries (over a minute each under the sanitizers) are left to the Release pass:
# tests/sanitizer_skip.txt names each with the lighter test that runs its code here.
skip="$(grep -v '^#' tests/sanitizer_skip.txt | awk 'NF { gsub(/\./, "\\.", $1); print $1 }' | paste -sd'|')"
echo "test: sanitizer pass skips $(grep -cv '^#' tests/sanitizer_skip.txt) tests (tests/sanitizer_skip.txt)"
(cd build-sanitize && ctest --output-on-failure -j"$(nproc)" -E "^(${skip})\$")

echo "test: fuzzers (libFuzzer, ASan + UBSan, ${FUZZ_SECONDS:-60} s each)"
unset ASAN_OPTIONS UBSAN_OPTIONS  # fuzz.sh sets its own; abort_on_error would hide libFuzzer's report
FUZZ_JOBS="$(nproc)" bash scripts/fuzz.sh
