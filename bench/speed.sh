#!/usr/bin/env bash
# The speed benchmark. Parts:
#   startup    whole process: `wavebrdf --version` (the start-up every command pays), the shared
#              libraries the binary loads (ldd), and `python3 -c "import wavebrdf"` against
#              `python3 -c pass`.
#   table      whole process, `wavebrdf genbrdf` against the reference program genBrdf (Yan et
#              al. 2018's public release, built separately; none of its code is in this
#              repository) on a generated 1024² heightfield, σ_p 10 µm, footprint at the centre
#              (512, 512): the README example (128², 8 wavelengths, light (−1, −1, 1), OHS;
#              target ≥ 150×) and each of the five models (128², λ 0.5, normal light; target
#              ≥ 30×). Without GENBRDF only wavebrdf is timed.
#   slice      whole process, `wavebrdf render` of a 1024² slice, σ_p 50 µm, λ 0.5, OHS, on the
#              same heightfield: `--path auto` against `--path separable`, double and float
#              (target ≥ 20×).
#   gradient   library: the gradient (forward + adjoint) against the forward of one 128² slice
#              per model (build/bin/models_bench, median of 3).
#   paths      library: the separable and fft paths (RenderOptions::path) over slice size n and
#              σ_p (OHS), with the fraction of single-precision peak of the matrix product
#              (8·n²·K flops) and, for fft, of the memory bandwidth a STREAM triad measures.
#              A path the library refuses prints n/a.
#   recovery   `wavebrdf recover --size 64 --resolution 48 --seed S` for SEEDS: wall time and
#              the final height_rel_rmse (metrics.csv).
# The whole-process parts (startup, table, slice) run the two programs of a row in turn (A B A B
# …, after one warm-up of each), RUNS times each, and report each one's minimum (the run least
# disturbed by the rest of the machine) and the ratio of the minima, each with the minimum CPU
# time (user + system, all threads; bench/whole_process.py), which a busy machine does not
# inflate the way it inflates the wall time.
# Usage:
#   [GENBRDF=/path/to/genBrdf] bash bench/speed.sh [--part startup|table|slice|gradient|paths|recovery]...
#       [--runs N] [--build DIR] [--seeds "S1 S2 S3"]
# Default: startup, table and slice (the whole-process targets); gradient and paths need the
# target models_bench (WAVEBRDF_BUILD_BENCH). Environment: GENBRDF (the reference binary; never
# committed), PEAK_SP_GFLOPS (nominal single-precision peak of this machine, default 166.4:
# 2 cores × 2.6 GHz × 32, the project's 2-core EPYC). Needs a Release build of wavebrdf_cli (and
# wavebrdf_python for the import time).
set -euo pipefail
cd "$(dirname "$0")/.."
root=$(pwd)

parts=()
runs=5
build=build
seeds="3001 3002 3003"
while [ $# -gt 0 ]; do
    case "$1" in
        --part) parts+=("$2"); shift 2 ;;
        --runs) runs=$2; shift 2 ;;
        --build) build=$2; shift 2 ;;
        --seeds) seeds=$2; shift 2 ;;
        -h|--help) sed -n '2,34p' "$0"; exit 0 ;;
        *) echo "speed.sh: unknown argument '$1' (expected --part, --runs, --build, --seeds)" >&2; exit 2 ;;
    esac
done
[ ${#parts[@]} -eq 0 ] && parts=(startup table slice)
for p in "${parts[@]}"; do
    case "$p" in startup|table|slice|gradient|paths|recovery) ;; *)
        echo "speed.sh: unknown part '$p' (expected startup, table, slice, gradient, paths or recovery)" >&2; exit 2 ;;
    esac
done
case "$runs" in ''|*[!0-9]*|0) echo "speed.sh: --runs '$runs' is not a positive integer" >&2; exit 2 ;; esac
if [ -n "${GENBRDF:-}" ] && [ ! -x "$GENBRDF" ]; then
    echo "speed.sh: GENBRDF='$GENBRDF' is not an executable file" >&2; exit 2
fi
W=$root/$build/bin/wavebrdf
B=$root/$build/bin/models_bench
peak=${PEAK_SP_GFLOPS:-166.4}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

want() { local p; for p in "${parts[@]}"; do [ "$p" = "$1" ] && return 0; done; return 1; }
seconds() {  # program args...: wall seconds of one run (output discarded), "failed" if it fails
    local s e
    s=$(date +%s.%N)
    if ! "$@" >/dev/null 2>"$work/last.err"; then
        echo "speed.sh: failed: $* ($(tail -1 "$work/last.err"))" >&2; echo failed; return
    fi
    e=$(date +%s.%N)
    echo "$e - $s" | bc
}
fmt() { case "$1" in failed|-) echo "$1" ;; *) printf "%.${2:-3}f" "$1" ;; esac; }

commit=$(git rev-parse --short HEAD 2>/dev/null || echo unknown)
git diff --quiet HEAD 2>/dev/null || commit="$commit (with uncommitted changes)"
echo "# wavebrdf speed (bench/speed.sh)"
echo "date:    $(date -u '+%Y-%m-%d %H:%M UTC')"
echo "commit:  $commit"
echo "machine: $(lscpu | sed -n 's/^Model name: *//p' | head -1), $(nproc) cores, nominal SP peak $peak GFLOP/s"
echo "build:   $build ($(sed -n 's/^CMAKE_BUILD_TYPE:STRING=//p' "$build/CMakeCache.txt" 2>/dev/null || echo '?'))"
echo "load:    $(cut -d' ' -f1-3 /proc/loadavg) (1, 5, 15 min) at the start"
echo "genBrdf: ${GENBRDF:-not given (only wavebrdf is timed)}"

# pairs LABEL TARGET -- A... -- B...: B and A in turn ($runs each after a warm-up of each), whole
# process; prints "| LABEL | min B | min A | B/A | TARGET |" (B: the reference side; none: only A).
pairs() {
    /usr/bin/python3 "$root/bench/whole_process.py" "${pair_runs:-$runs}" "$@"
}

if want startup || want table || want slice; then
    "$W" heightfield --type isotropic --size 1024 --rms-height-um 0.05 --correlation-um 4 --seed 1 \
        --out "$work/iso1024.exr" --no-png --quiet
fi

if want startup; then
    echo
    # Start-up is milliseconds: many more runs than the slow rows, so that the minimum is one
    # the rest of the machine did not disturb.
    pair_runs=$((runs * 10))
    echo "## Start-up (whole process, minimum of $pair_runs after one warm-up, alternating)"
    echo
    echo "Shared libraries \`wavebrdf\` loads: $(ldd "$W" | wc -l) (\`ldd $build/bin/wavebrdf | wc -l\`)."
    echo
    echo "| case | baseline [s] | wavebrdf [s] | ratio | target |"
    echo "|---|---|---|---|---|"
    pairs "\`wavebrdf --version\` (baseline: \`/bin/true\`)" "< 5 ms" -- "$W" --version -- /bin/true
    if [ -d "$root/$build/python/wavebrdf" ]; then
        PYTHONPATH="$root/$build/python" pairs "\`python3 -c 'import wavebrdf'\` (baseline: \`python3 -c pass\`)" \
            "" -- /usr/bin/python3 -c "import wavebrdf" -- /usr/bin/python3 -c pass
    fi
    unset pair_runs
fi

if want table; then
    echo
    echo "## Whole process against genBrdf (1024² heightfield, σ_p 10 µm, footprint at the centre; minimum of $runs, alternating)"
    echo
    echo "| case | genBrdf [s] | wavebrdf genbrdf [s] | ratio | target |"
    echo "|---|---|---|---|---|"
    table_row() {  # label, target, then the genBrdf arguments both programs take
        local label=$1 target=$2
        shift 2
        local ref=()
        [ -n "${GENBRDF:-}" ] && ref=("$GENBRDF" -i "$work/iso1024.exr" -o "$work/ref.exr" "$@")
        pairs "$label" "$target" -- "$W" genbrdf -i "$work/iso1024.exr" -o "$work/ours.exr" "$@" --quiet \
            -- "${ref[@]}"
    }
    centre=(-x 512 -y 512 -p 10 -r 128)
    table_row "README example: 128², 8 wavelengths, light (−1,−1,1), OHS" "≥ 150×" "${centre[@]}" -l 0 -s -1 -t -1 -d OHS
    for m in OHS GHS ROHS RGHS Kirchhoff; do
        table_row "128², λ 0.5, normal light, $m" "≥ 30×" "${centre[@]}" -l 0.5 -d "$m"
    done
fi

if want slice; then
    echo
    echo "## 1024² slice, σ_p 50 µm: \`--path auto\` against \`--path separable\` (whole process, minimum of $runs, alternating)"
    echo
    echo "| precision | separable [s] | auto [s] | ratio | target |"
    echo "|---|---|---|---|---|"
    for precision in double float; do
        slice=("$W" render --heightfield "$work/iso1024.exr" --x-um 512 --y-um 512 --sigma-p-um 50 --lambda-um 0.5
               --resolution 1024 --precision "$precision" --out "$work/slice.exr" --quiet)
        pairs "$precision" "≥ 20×" -- "${slice[@]}" --path auto -- "${slice[@]}" --path separable
    done
fi

bench_json() {  # filter, output file: models_bench, median of 3 (one warm-up each)
    "$B" --benchmark_filter="$1" --benchmark_repetitions=3 --benchmark_report_aggregates_only=true \
        --benchmark_min_time=0.05 --benchmark_format=json --benchmark_out="$2" --benchmark_out_format=json \
        >/dev/null 2>"$work/bench.err" || { cat "$work/bench.err" >&2; exit 1; }
}

if want gradient; then
    bench_json '^model_' "$work/models.json"
    echo
    echo "## Gradient against forward (library, one 128² slice, λ 0.5, normal light, float, σ_p 10 µm; median of 3)"
    echo
    /usr/bin/python3 - "$work/models.json" <<'EOF'
import json, sys
runs, kernels = {}, {}
for b in json.load(open(sys.argv[1]))["benchmarks"]:
    name = b["name"].split("/real_time")[0]
    if b.get("error_occurred"):
        runs[name] = None
    elif b.get("aggregate_name") == "median":
        runs[name] = b["real_time"]  # ms
        kernels[name.split("/")[1]] = "%d" % b["kernels"]
print("| model | kernels | forward [ms] | gradient [ms] | gradient / forward |")
print("|---|---|---|---|---|")
for m in ["OHS", "GHS", "ROHS", "RGHS", "Kirchhoff"]:
    f, g = runs.get("model_forward/" + m), runs.get("model_gradient/" + m)
    cell = lambda t: "n/a" if t is None else "%.1f" % t
    ratio = "n/a" if f is None or g is None else "%.2f×" % (g / f)
    print("| %s | %s | %s | %s | %s |" % (m, kernels.get(m, "?"), cell(f), cell(g), ratio))
EOF
fi

if want paths; then
    bench_json '^(path/|triad)' "$work/paths.json"
    echo
    echo "## Separable and FFT paths (library, OHS slice n², λ 0.5, normal light, float; median of 3)"
    echo
    /usr/bin/python3 - "$work/paths.json" "$peak" <<'EOF'
import json, sys
peak = float(sys.argv[2]) * 1e9
runs, refused, triad = {}, {}, None
for b in json.load(open(sys.argv[1]))["benchmarks"]:
    name = b["name"].split("/real_time")[0].split("/min_time")[0]
    if b.get("error_occurred"):
        refused[name] = b.get("error_message", "")
    elif b.get("aggregate_name") == "median":
        if name == "triad":
            triad = b["bytes_per_second"]
        else:
            runs[name] = b
print("Memory bandwidth (STREAM triad, all threads, 3 × 64 MiB): %.1f GB/s" % (triad / 1e9))
print()
print("| n | σ_p [µm] | kernels | separable [ms] | GFLOP/s | % of SP peak | fft [ms] | fft speed-up | fft GB/s (≥) | % of bandwidth (≥) |")
print("|---|---|---|---|---|---|---|---|---|---|")
for sigma in (10, 50):
    for n in (128, 256, 512, 1024):
        s = runs.get("path/separable/%d/%d" % (n, sigma))
        f = runs.get("path/fft/%d/%d" % (n, sigma))
        row = [str(n), str(sigma)]
        any_run = s or f
        row.append("%d" % any_run["kernels"] if any_run else "?")
        if s:
            t = s["real_time"] * 1e-3
            row += ["%.1f" % s["real_time"], "%.0f" % (s["flops"] / t / 1e9), "%.0f %%" % (100 * s["flops"] / t / peak)]
        else:
            row += ["n/a", "n/a", "n/a"]
        if f:
            t = f["real_time"] * 1e-3
            speedup = "%.1f×" % (s["real_time"] / f["real_time"]) if s else "n/a"
            bw = f["bytes_min"] / t
            row += ["%.1f" % f["real_time"], speedup, "%.1f" % (bw / 1e9), "%.0f %%" % (100 * bw / triad)]
        else:
            row += ["n/a"] * 4
        print("| " + " | ".join(row) + " |")
notes = sorted(set(refused.values()))
if notes:
    print()
    print("n/a: " + "; ".join(notes))
print()
print("fft bandwidth: a lower bound on its traffic (48·n² bytes: a complex-float grid of at least n² points")
print("written once, read and written by the two FFT passes, read once), divided by the median time.")
EOF
fi

if want recovery; then
    echo
    echo "## Recovery (\`wavebrdf recover --size 64 --resolution 48 --seed S\`, whole process, one run each)"
    echo
    echo "| seed | time [s] | height_rel_rmse |"
    echo "|---|---|---|"
    for seed in $seeds; do
        case "$seed" in ''|*[!0-9]*) echo "speed.sh: seed '$seed' is not a non-negative integer" >&2; exit 2 ;; esac
        t=$(seconds "$W" recover --size 64 --resolution 48 --seed "$seed" --out "$work/recover-$seed" --no-plots --quiet)
        err=$(awk -F, 'NR > 1 && $5 != "nan" {v = $5} END {if (v == "") print "n/a"; else printf "%.4f %%", 100 * v}' \
            "$work/recover-$seed/metrics.csv" 2>/dev/null || echo "n/a")
        echo "| $seed | $(fmt "$t" 1) | $err |"
    done
fi

echo
echo "load at the end: $(cut -d' ' -f1-3 /proc/loadavg) (1, 5, 15 min)"
