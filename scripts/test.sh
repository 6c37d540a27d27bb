#!/usr/bin/env bash
# Sets up, builds and runs every test: the Release build (GCC), then the same suite built with
# clang, AddressSanitizer and UndefinedBehaviorSanitizer (compiled in the background, at the lowest
# priority, while the Release build's checks run), then the fuzzers (scripts/fuzz.sh, FUZZ_SECONDS
# each, default 5). Prints the wall time of each phase at the end (CI's budget: 30 minutes on
# 2 cores, from a fresh machine).
set -euo pipefail
cd "$(dirname "$0")/.."

phases=()
phase_name=""
phase_start=$SECONDS
phase() {  # phase NAME: closes the previous phase's clock and opens NAME's
    [ -z "$phase_name" ] || phases+=("$(printf '%6d s  %s' $((SECONDS - phase_start)) "$phase_name")")
    phase_name="$1"
    phase_start=$SECONDS
    [ -z "$phase_name" ] || echo "test: $phase_name"
}
report_phases() {
    phase ""
    echo "test: wall time per phase"
    printf '  %s\n' "${phases[@]}"
    printf '%8d s  in all\n' "$SECONDS"
}
trap '[ -z "${sanitize_pid:-}" ] || kill -- -"$sanitize_pid" 2>/dev/null; report_phases' EXIT

# ccache compares paths relative to the checkout (also on a machine whose ccache has no base_dir),
# so that the pip package's build (build-pip/, at build/'s depth) finds what the Release build
# compiled: the same library, the same flags. With CCACHE_DISABLE set (no cache from before this
# run, as on a new machine) those two builds share this run's own cache, emptied here; the other
# builds compile without one.
export CCACHE_BASEDIR="${CCACHE_BASEDIR:-$PWD}"
run_cache=""
if [ -n "${CCACHE_DISABLE:-}" ]; then  # (setup.sh installs ccache, if it is not there yet)
    run_cache="$PWD/build-ccache"
    rm -rf "$run_cache"
fi
with_run_cache() {  # command...: with this run's cache, where CCACHE_DISABLE asked for one
    if [ -n "$run_cache" ]; then env -u CCACHE_DISABLE CCACHE_DIR="$run_cache" "$@"; else "$@"; fi
}

phase "layering and function length (scripts/check_layers.py, check_function_length.py)"
/usr/bin/python3 scripts/check_layers.py  # src/ includes run down the stages only
/usr/bin/python3 scripts/check_function_length.py  # no function in src/ over 200 lines
phase "setup and Release build"
with_run_cache bash scripts/setup.sh -DWAVEBRDF_BUILD_PYTHON=ON  # explicit: an older build/ may have it cached OFF
# clang, not GCC (the Release pass's compiler): with ASan + UBSan GCC 12 takes 2.5-3 times the
# CPU to compile (src/recovery/recover.cpp 38 s against 12 s; tests/recover_test.cpp 38 against
# 17), and a second compiler checks the code as well. -O2, not -O1: -O1 compiles this build in
# 0.63 of the CPU, but its tests run about 1.2 times as long (the design's loops are not
# vectorised), and in a whole CI run the two nearly cancel (2320 s against 2445 s, the tests 799 s
# against 672: bench/results/2026-12-02-ci-time.md). Line tables only (-g1): the reports still
# name every frame's function, file and line. The same build holds the fuzzers, so the
# instrumented library is compiled once; shared, so that each fuzzer's link is its own small
# file. libFuzzer's coverage goes into the readers the fuzzers call only (CMakeLists.txt,
# WAVEBRDF_FUZZED_SOURCES): in the whole library it made the sanitizer tests 3-4 times slower.
# The tests' own sources at the build's -O2 too (WAVEBRDF_TESTS_OPT empty; the Release build
# compiles them at -O1): at -O0 they compiled in 211 CPU-s against 558, but the library code
# inlined into them ran unoptimised under ASan and the tests took 1061 s against 672. At -O1 (on the
# current machine) they compiled in 393 CPU-s against 434 and the tests took 28 CPU-s more: no gain
# (bench/results/2026-12-03-ci-cpu.md).
# Compiled in batches (WAVEBRDF_UNITY_BUILD, as the Release build): the readers that carry
# libFuzzer's coverage stay out of the batches, their flags being their own. The consumer's build
# (scripts/test_consumer.sh) compiles every source file alone, so a missing #include that a batch
# hides still fails CI.
# Eigen's headers are compiled without the sanitizers' checks (cmake/sanitizer_ignorelist.txt):
# instrumented, they took over a third of the sanitizer tests' CPU time. In their place the build
# keeps assertions on (no -DNDEBUG), so that Eigen checks its own indices, blocks and sizes (the
# pass: 400 s wall against 628 on the idle machine; bench/results/2026-12-03-sanitizer-eigen.md).
# It starts as soon as the Release build is done, in the background at the lowest priority
# (nice 19), so that it takes only the CPU time the Release tests, pytest and the package checks
# leave idle (processes waiting for the CLI they started, a serial Python, single-threaded links)
# and slows none of them; what is left of it runs after them. Its output goes to
# build-sanitize/build.log, shown when it is joined.
launcher=()  # ccache, where the machine has it, as in setup.sh (a fresh CI machine has none)
command -v ccache >/dev/null 2>&1 && launcher=(-DCMAKE_C_COMPILER_LAUNCHER=ccache -DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
sanitize_build() {
    CC=clang CXX=clang++ cmake -S . -B build-sanitize -DCMAKE_BUILD_TYPE=RelWithDebInfo \
          -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O2 -g1" -DWAVEBRDF_SANITIZE=ON -DWAVEBRDF_BUILD_FUZZERS=ON \
          -DWAVEBRDF_SHARED=ON -DWAVEBRDF_BUILD_BENCH=OFF -DWAVEBRDF_BUILD_PYTHON=OFF -DWAVEBRDF_BUILD_EXPERIMENTS=OFF \
          -DWAVEBRDF_UNITY_BUILD=ON -DWAVEBRDF_TESTS_OPT= "${launcher[@]}" >/dev/null
    cmake --build build-sanitize -j"$(nproc)"
}
sanitize_pid=""
sanitize_start() {
    mkdir -p build-sanitize
    sanitize_started=$SECONDS
    # Its own process group (set -m), so that a failing run stops the whole build.
    set -m
    ( renice -n 19 -p "$BASHPID" >/dev/null; sanitize_build ) >build-sanitize/build.log 2>&1 &
    sanitize_pid=$!
    set +m
    echo "test: sanitizer build started in the background (nice 19; build-sanitize/build.log)"
}
sanitize_wait() {
    local rc=0
    # The rest at the priority of the phases before it (raising it back needs root; elsewhere it
    # stays at 19, which on a machine of its own changes nothing).
    renice -n 0 -g "$sanitize_pid" >/dev/null 2>&1 || true
    wait "$sanitize_pid" || rc=$?
    sanitize_pid=""
    cat build-sanitize/build.log
    echo "test: sanitizer build took $((SECONDS - sanitize_started)) s, in the background from the Release build on"
    [ "$rc" = 0 ] || { echo "test: FAILED: the sanitizer build (exit $rc)"; exit 1; }
}
sanitize_start
phase "Release tests (ctest)"
# ctest runs nproc tests at once and each test nproc OpenMP threads: threads that spin at their
# barriers (the default policy) take the cores from the other test's work; sleeping ones do not
# (the design tests ran 20-50x slower in pairs: bench/results/2026-11-30-ci-omp-wait.md).
ctest_threads=(env OMP_WAIT_POLICY=passive)
(cd build && "${ctest_threads[@]}" ctest --output-on-failure -j"$(nproc)")
/usr/bin/python3 scripts/slowest_tests.py build  # docs/reliability.md quotes these
phase "Python (pytest)"
/usr/bin/python3 -m pytest -q tests/python
phase "API reference (scripts/docs.sh)"
bash scripts/docs.sh  # the API reference (Doxygen + pydoc) builds without warnings
phase "C++ package (scripts/test_consumer.sh)"
JOBS="$(nproc)" bash scripts/test_consumer.sh  # find_package against an install, and add_subdirectory
phase "pip package (scripts/test_pip.sh)"
with_run_cache bash scripts/test_pip.sh  # pip install in a fresh venv, smoke test outside the tree

phase "sanitizer build: the rest (waiting for the background build)"
sanitize_wait
phase "sanitizer tests (ctest)"
# Allocation and free stacks of 8 frames, not ASan's 30: every malloc and free records one, and
# the recoveries allocate in their loops (bench/results/2026-12-02-ci-time.md); a report still
# names the allocating function and its callers, and a rerun with the default gives the rest.
# A quarantine of 32 MB, not ASan's 256: freed memory waits there before it is reused, so that a
# use after free finds it poisoned. With 256 MB the recoveries' loops, which allocate, kept
# touching fresh pages: 28 % of the pass's CPU time was the kernel's (page faults), 24 % with
# 32 MB, which still finds a use of anything among the last 32 MB freed. The whole pass: 608 s
# against 737 (1160 CPU-s against 1416; bench/results/2026-12-02-asan-quarantine.md).
export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1:malloc_context_size=8:quarantine_size_mb=32
export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
# Slow tests whose every line of our code the kept tests run are left to the Release pass:
# tests/sanitizer_skip.txt, written by scripts/sanitizer_skip.py from each test's line coverage,
# names each with the kept test that runs most of its lines.
skip="$(grep -v '^#' tests/sanitizer_skip.txt | awk 'NF { gsub(/\./, "\\.", $1); print $1 }' | paste -sd'|')"
echo "test: sanitizer pass skips $(grep -cv '^#' tests/sanitizer_skip.txt) tests (tests/sanitizer_skip.txt)"
(cd build-sanitize && "${ctest_threads[@]}" ctest --output-on-failure -j"$(nproc)" -E "^(${skip})\$")
/usr/bin/python3 scripts/slowest_tests.py build-sanitize

# Each target's saved inputs and seeds, then FUZZ_SECONDS of fuzzing (default here 5: a check
# that nothing found before comes back and that a short run finds nothing; every saved input is
# rerun whatever the seconds; scripts/fuzz.sh alone fuzzes 60 s a target, longer when asked).
fuzz_seconds="${FUZZ_SECONDS:-5}"
phase "fuzzers (libFuzzer, ASan + UBSan, ${fuzz_seconds} s each)"
unset ASAN_OPTIONS UBSAN_OPTIONS  # fuzz.sh sets its own; abort_on_error would hide libFuzzer's report
FUZZ_BUILD=build-sanitize FUZZ_SECONDS="$fuzz_seconds" FUZZ_JOBS="$(nproc)" bash scripts/fuzz.sh
