#!/usr/bin/env bash
# Builds the libFuzzer targets (fuzz/) with clang, ASan and UBSan into build-fuzz/ and runs each
# for a bounded time over a copy of its seed corpus (fuzz/corpus/<target>/; the tree is never
# written). First each target reruns its saved inputs (fuzz/regressions/<target>/). Fails when
# one of those fails again or fuzzing finds a crash, leak, timeout or out-of-memory; new inputs
# that did are kept in <build>/findings/<target>/.
# Usage: bash scripts/fuzz.sh [target...]     (default: every target)
# Environment: FUZZ_SECONDS (per target, default 60), FUZZ_JOBS (build parallelism and targets run
# at once, default 2), FUZZ_BUILD (a build directory already configured by the caller with
# clang and -DWAVEBRDF_BUILD_FUZZERS=ON, as scripts/test.sh's sanitizer build is; default:
# build-fuzz/, configured here).
set -euo pipefail
cd "$(dirname "$0")/.."

seconds="${FUZZ_SECONDS:-60}"
jobs="${FUZZ_JOBS:-2}"
targets=("$@")
# observations_hdf5_bytes mutates the bytes of HDF5 files, which exercises HDF5's own parser more
# than our reader, and HDF5 1.10 overflows and leaks on some malformed headers (fuzz/README.md).
# Unless named, it only reruns its saved inputs and seeds; observations_hdf5 fuzzes our reader.
# surface_datx (Zygo datx, HDF5 bytes) likewise.
replay_only=()
[ ${#targets[@]} -gt 0 ] || replay_only=(observations_hdf5_bytes surface_datx)
[ ${#targets[@]} -gt 0 ] || targets=(exr positions_json observations_json checkpoint observations_hdf5 observations_hdf5_bytes table
                                     iridescent_spec png_picture run_json surface_x3p surface_sdf surface_plu surface_sur surface_al3d
                                     surface_metropro surface_npy surface_text surface_datx)

build="${FUZZ_BUILD:-build-fuzz}"
if [ -z "${FUZZ_BUILD:-}" ]; then
    launcher=()
    if command -v ccache >/dev/null 2>&1; then
        launcher=(-DCMAKE_C_COMPILER_LAUNCHER=ccache -DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
    fi
    # One shared instrumented library (WAVEBRDF_SHARED) that every target loads: each target's link
    # is then its own small file, not a copy of the whole library.
    CC=clang CXX=clang++ cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
        -DWAVEBRDF_BUILD_FUZZERS=ON -DWAVEBRDF_SHARED=ON -DWAVEBRDF_BUILD_TESTS=OFF -DWAVEBRDF_BUILD_BENCH=OFF \
        -DWAVEBRDF_BUILD_PYTHON=OFF -DWAVEBRDF_BUILD_EXPERIMENTS=OFF "${launcher[@]}" >/dev/null
elif ! grep -q '^WAVEBRDF_BUILD_FUZZERS:BOOL=ON$' "$build/CMakeCache.txt" 2>/dev/null; then
    echo "fuzz: FUZZ_BUILD=$build is not a build configured with -DWAVEBRDF_BUILD_FUZZERS=ON"
    exit 1
fi
build_targets=()
for t in "${targets[@]}"; do build_targets+=(--target "${t}_fuzz"); done
cmake --build "$build" -j"$jobs" "${build_targets[@]}"

# The largest input worth mutating: the seeds are under 3 kB; larger inputs mostly repeat.
max_len() {
    case "$1" in
        exr|checkpoint|table|png_picture|surface_*) echo 16384 ;;
        observations_hdf5_bytes) echo 32768 ;;  # an HDF5 file of two 4x4 slices is 18 kB
        observations_hdf5) echo 1024 ;;  # a recipe: about one byte per choice
        *) echo 8192 ;;
    esac
}

# The largest single allocation allowed before libFuzzer reports out-of-memory. EXR: 256 MB, so
# a small file declaring a huge image is reported at once (should a reader stop capping the pixel
# count before allocating; see fuzz/README.md) rather than grinding through gigabytes.
malloc_limit() {
    case "$1" in
        exr|table|png_picture|surface_*) echo 256 ;;
        *) echo 2048 ;;
    esac
}

work="$(mktemp -d "${TMPDIR:-/tmp}/wavebrdf-fuzz.XXXXXX")"
trap 'rm -rf "$work"' EXIT
# The targets' scratch files (fuzz/fuzz_util.h) too: a crashed target cannot remove its own.
mkdir -p "$work/tmp"
export TMPDIR="$work/tmp"
findings="$PWD/$build/findings"
export ASAN_OPTIONS="detect_leaks=1:allocator_may_return_null=0${ASAN_OPTIONS:+:$ASAN_OPTIONS}"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1${UBSAN_OPTIONS:+:$UBSAN_OPTIONS}"
# One target: its saved inputs once each, then fuzzing for $seconds. Prints its log lines and
# writes what failed (one input or target name per line) to $work/$t.failed; always returns 0,
# so that targets running side by side report each other's results.
run_target() {  # target
    local t="$1"
    : >"$work/$t.failed"
    rm -rf "${findings:?}/$t"
    mkdir -p "$work/$t" "$findings/$t"
    cp -R "fuzz/corpus/$t/." "$work/$t/"
    # Field names and tricky numbers (fuzz/dict/) get the mutations past the first checks sooner.
    local dict=()
    if [ "$t" = exr ] || [ "$t" = table ]; then
        dict=(-dict=fuzz/dict/exr.dict)
    elif [ "$t" = png_picture ]; then
        dict=(-dict=fuzz/dict/png.dict)
    elif [ -f "fuzz/dict/$t.dict" ]; then
        cat fuzz/dict/json_common.dict "fuzz/dict/$t.dict" >"$work/$t.dict"
        dict=(-dict="$work/$t.dict")
    fi
    local limits=(-timeout=10 -rss_limit_mb=2048 -malloc_limit_mb="$(malloc_limit "$t")")
    # Both HDF5 targets load HDF5, which leaks on some error paths of its own: fuzz/lsan_hdf5.supp
    # names the calls and the upstream reports. Slow unwinding names HDF5's frames (it is built
    # without frame pointers), so that the suppressions match those calls only.
    if [ "$t" = observations_hdf5 ] || [ "$t" = observations_hdf5_bytes ]; then
        export LSAN_OPTIONS="suppressions=$PWD/fuzz/lsan_hdf5.supp"
        export ASAN_OPTIONS="$ASAN_OPTIONS:fast_unwind_on_malloc=0"
    fi    # Inputs that once failed (fuzz/regressions/<target>/, see fuzz/README.md) run first, once each.
    local regressions=(fuzz/regressions/"$t"/*)
    if [ -e "${regressions[0]}" ]; then
        echo "fuzz: $t: ${#regressions[@]} regression input(s)"
        for input in "${regressions[@]}"; do  # one at a time: libFuzzer stops at the first failure
            if ! "$build/bin/${t}_fuzz" "${limits[@]}" "$input" </dev/null >"$work/$t.regression.log" 2>&1; then
                echo "$input" >>"$work/$t.failed"
                grep -E 'ERROR|runtime error|SUMMARY' "$work/$t.regression.log" | head -n 3
                echo "fuzz: $t: $input fails again"
            fi
        done
    fi
    if [[ " ${replay_only[*]} " == *" $t "* ]]; then
        echo "fuzz: $t: its seeds once each (named on the command line, it fuzzes)"
        if ! "$build/bin/${t}_fuzz" "${limits[@]}" -runs=0 "$work/$t" </dev/null >"$work/$t.log" 2>&1; then
            echo "$t" >>"$work/$t.failed"
            tail -n 60 "$work/$t.log"
        fi
        return 0
    fi
    echo "fuzz: $t for ${seconds} s"
    # New corpus entries go to the copy; crash/leak/timeout/oom inputs to findings/<target>/.
    if ! "$build/bin/${t}_fuzz" "$work/$t" "${dict[@]}" \
            -max_total_time="$seconds" -max_len="$(max_len "$t")" "${limits[@]}" -print_final_stats=1 \
            -artifact_prefix="$findings/$t/" </dev/null >"$work/$t.log" 2>&1; then
        echo "$t" >>"$work/$t.failed"
        tail -n 60 "$work/$t.log"
        echo "fuzz: $t FAILED; inputs in $findings/$t/"
    else
        grep -E '^(Done|stat::number_of_executed_units|stat::new_units_added)' "$work/$t.log" || true
    fi
    return 0
}

# FUZZ_JOBS targets at a time (each libFuzzer process is single-threaded); each one's lines are
# printed together once it is done.
running=0
for t in "${targets[@]}"; do
    run_target "$t" >"$work/$t.out" 2>&1 &
    running=$((running + 1))
    if [ "$running" -ge "$jobs" ]; then
        wait -n
        running=$((running - 1))
    fi
done
wait
failed=()
for t in "${targets[@]}"; do
    cat "$work/$t.out"
    while IFS= read -r line; do failed+=("$line"); done <"$work/$t.failed"
done
if [ ${#failed[@]} -gt 0 ]; then
    echo "fuzz: FAILED: ${failed[*]} (fuzz/README.md says how to reproduce and minimise)"
    exit 1
fi
echo "fuzz: no findings in ${targets[*]}"
