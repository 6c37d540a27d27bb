#!/usr/bin/env bash
# The scaling benchmark (docs/scale.md, "Measured"): `wavebrdf recover` under
# `mpiexec -n K` for K in RANKS (default 1 2 3 4), whole process.
#   strong   the same tile (--size N, default 64, --resolution 48) on every K: ideally the wall
#            time falls as 1/K and the heights are the same bits as on one rank (checked: the
#            column "= 1 rank" compares estimate_height.npy with the one-rank run's).
#   weak     the tile area proportional to K (size round(N·√K)): ideally the wall time stays.
# Per row: wall time of the whole mpiexec, user CPU and peak RSS per rank (the largest over the
# ranks, and the CPU summed over them), the final height_rel_rmse; each the median of RUNS
# (default 3) runs. Threads per rank: THREADS (default: the cores / K, at least 1). Ranks ×
# threads beyond the cores are oversubscribed: the output says so per row.
# Usage:
#   bash bench/scale.sh [--size N] [--resolution R] [--ranks "1 2 3 4"] [--runs N] [--seed S]
#       [--threads T] [--mode strong|weak|both] [--passive] [--build DIR] [--out FILE] [--note TEXT]
# --passive: OMP_WAIT_POLICY=passive and OMPI_MCA_mpi_yield_when_idle=1 for every rank (waiting
# threads and ranks sleep instead of spinning; docs/scale.md, "Waiting"). --out: the report
# (default bench/results/scale-YYYY-MM-DD.md; '-' for stdout only); it is also printed.
# Needs a Release build with MPI (wavebrdf_cli) and mpiexec on PATH (or MPIEXEC).
set -euo pipefail
cd "$(dirname "$0")/.."
root=$(pwd)

size=64
resolution=48
ranks="1 2 3 4"
runs=3
seed=5401
threads=""
mode=both
passive=0
build=build
out=""
note=""
while [ $# -gt 0 ]; do
    case "$1" in
        --size) size=$2; shift 2 ;;
        --resolution) resolution=$2; shift 2 ;;
        --ranks) ranks=$2; shift 2 ;;
        --runs) runs=$2; shift 2 ;;
        --seed) seed=$2; shift 2 ;;
        --threads) threads=$2; shift 2 ;;
        --mode) mode=$2; shift 2 ;;
        --passive) passive=1; shift ;;
        --build) build=$2; shift 2 ;;
        --out) out=$2; shift 2 ;;
        --note) note=$2; shift 2 ;;
        -h|--help) sed -n '2,21p' "$0"; exit 0 ;;
        *) echo "scale.sh: unknown argument '$1' (see --help)" >&2; exit 2 ;;
    esac
done
positive() {  # name value: exits unless value is a positive integer
    case "$2" in ''|*[!0-9]*|0) echo "scale.sh: $1 '$2' is not a positive integer" >&2; exit 2 ;; esac
}
positive --size "$size"
positive --resolution "$resolution"
positive --runs "$runs"
case "$seed" in ''|*[!0-9]*) echo "scale.sh: --seed '$seed' is not a non-negative integer" >&2; exit 2 ;; esac
[ -n "$threads" ] && positive --threads "$threads"
for k in $ranks; do positive "--ranks entry" "$k"; done
case "$mode" in strong|weak|both) ;; *) echo "scale.sh: --mode '$mode' is not strong, weak or both" >&2; exit 2 ;; esac
W=$root/$build/bin/wavebrdf
[ -x "$W" ] || { echo "scale.sh: $W is missing (build the target wavebrdf_cli)" >&2; exit 2; }
MPIEXEC=${MPIEXEC:-$(command -v mpiexec || true)}
[ -n "$MPIEXEC" ] || { echo "scale.sh: mpiexec not found (Debian: openmpi-bin; or set MPIEXEC)" >&2; exit 2; }
[ -z "$out" ] && out=$root/bench/results/scale-$(date -u +%Y-%m-%d).md
cores=$(nproc)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
# Running OpenMPI as root (containers, CI) needs its consent; harmless otherwise.
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1

median() { sort -g | awk '{a[NR]=$1} END {print (NR % 2) ? a[(NR+1)/2] : (a[NR/2] + a[NR/2+1]) / 2}'; }

# One run: K ranks, tile size S, into $work/run; prints "wall user_max user_sum rss_max_kb rmse".
# Every rank runs under /usr/bin/time writing its own file (the rank from OpenMPI's environment).
one_run() {
    local k=$1 s=$2 t=$3 dir=$work/run start end
    rm -rf "$dir" "$work"/time.*
    local env_args=(-x OMP_NUM_THREADS="$t")
    [ "$passive" = 1 ] && env_args+=(-x OMP_WAIT_POLICY=passive -x OMPI_MCA_mpi_yield_when_idle=1)
    start=$(date +%s.%N)
    if ! "$MPIEXEC" -q -n "$k" --oversubscribe --bind-to none "${env_args[@]}" \
        bash -c 'exec /usr/bin/time -f "%U %M" -o "$0.${OMPI_COMM_WORLD_RANK:-0}" "$@"' "$work/time" \
        "$W" recover --size "$s" --resolution "$resolution" --seed "$seed" --out "$dir" --quiet --no-plots \
        >"$work/last.out" 2>"$work/last.err"; then
        echo "scale.sh: failed: $k ranks, size $s ($(tail -1 "$work/last.err"))" >&2
        echo "failed"
        return
    fi
    end=$(date +%s.%N)
    local wall user_max user_sum rss_max rmse
    wall=$(echo "$end - $start" | bc)
    user_max=$(cat "$work"/time.* | awk '{ if ($1 > m) m = $1 } END { print m }')
    user_sum=$(cat "$work"/time.* | awk '{ s += $1 } END { print s }')
    rss_max=$(cat "$work"/time.* | awk '{ if ($2 > m) m = $2 } END { print m }')
    rmse=$(awk -F, 'NR > 1 && $5 != "nan" {v = $5} END {if (v == "") print "nan"; else print v}' "$dir/metrics.csv")
    echo "$wall $user_max $user_sum $rss_max $rmse"
}

# Median of $runs runs of one configuration: prints the Markdown row.
row() {
    local kind=$1 k=$2 s=$3 t=$k_threads r line walls=() umax=() usum=() rss=() rmse=nan equal=-
    for r in $(seq "$runs"); do
        line=$(one_run "$k" "$s" "$t")
        [ "$line" = failed ] && { echo "| $kind | $k | ${s}² | $t | failed | | | | | |"; return; }
        read -r w a b m e <<<"$line"
        walls+=("$w"); umax+=("$a"); usum+=("$b"); rss+=("$m"); rmse=$e
    done
    if [ "$kind" = strong ]; then
        if [ "$k" = "$first_rank" ]; then
            cp "$work/run/estimate_height.npy" "$work/strong_reference.npy"
            equal="(reference)"
        elif cmp -s "$work/run/estimate_height.npy" "$work/strong_reference.npy"; then
            equal="yes"
        else
            equal="NO"
        fi
    fi
    local over=""
    [ $((k * t)) -gt "$cores" ] && over=" (oversubscribed: $((k * t)) threads on $cores cores)"
    printf '| %s | %s%s | %s² | %s | %.1f | %.1f | %.1f | %.0f | %.4f %% | %s |\n' "$kind" "$k" "$over" "$s" "$t" \
        "$(printf '%s\n' "${walls[@]}" | median)" "$(printf '%s\n' "${umax[@]}" | median)" \
        "$(printf '%s\n' "${usum[@]}" | median)" "$(echo "$(printf '%s\n' "${rss[@]}" | median) / 1024" | bc -l)" \
        "$(echo "100 * $rmse" | bc -l)" "$equal"
}

load_start=$(cut -d' ' -f1-3 /proc/loadavg)
commit=$(git rev-parse --short HEAD 2>/dev/null || echo unknown)
git diff --quiet HEAD 2>/dev/null || commit="$commit (with uncommitted changes)"
first_rank=$(echo "$ranks" | awk '{print $1}')
{
    echo "# wavebrdf MPI scaling (bench/scale.sh)"
    echo
    echo "- date: $(date -u '+%Y-%m-%d %H:%M UTC')"
    echo "- commit: $commit"
    echo "- machine: $(lscpu | sed -n 's/^Model name: *//p' | head -1), $cores cores, $(free -g | awk '/^Mem:/ {print $2}') GB"
    echo "- build: $build ($(sed -n 's/^CMAKE_BUILD_TYPE:STRING=//p' "$build/CMakeCache.txt" 2>/dev/null || echo '?'))," \
        "$("$MPIEXEC" --version 2>/dev/null | head -1)"
    echo "- run: \`recover --size N --resolution $resolution --seed $seed\`, median of $runs run(s)," \
        "$([ "$passive" = 1 ] && echo "OMP_WAIT_POLICY=passive, OMPI_MCA_mpi_yield_when_idle=1" || echo "default waiting (spinning)")"
    echo "- load (1, 5, 15 min) at the start: $load_start"
    [ -n "$note" ] && echo "- note: $note"
} >"$work/report.md"
cat "$work/report.md"
{
    echo
    echo "| scaling | ranks | tile | threads per rank | wall [s] | user CPU, max rank [s] | user CPU, all ranks [s] | peak RSS, max rank [MB] | height_rel_rmse | = 1 rank |"
    echo "|---|---|---|---|---|---|---|---|---|---|"
} | tee -a "$work/report.md"
for kind in strong weak; do
    [ "$mode" = both ] || [ "$mode" = "$kind" ] || continue
    for k in $ranks; do
        k_threads=${threads:-$((cores / k > 0 ? cores / k : 1))}
        s=$size
        [ "$kind" = weak ] && s=$(echo "$size * sqrt($k) + 0.5" | bc -l | cut -d. -f1)
        row "$kind" "$k" "$s" | tee -a "$work/report.md"
    done
done
load_end=$(cut -d' ' -f1-3 /proc/loadavg)
{
    echo
    echo "Load (1, 5, 15 min) at the end: $load_end. Ranks beyond the cores share them (oversubscribed):"
    echo "their wall time measures the sharing, not the scaling; user CPU and peak RSS per rank do not depend on it."
} | tee -a "$work/report.md"
if [ "$out" != - ]; then
    mkdir -p "$(dirname "$out")"
    cp "$work/report.md" "$out"
    echo "written: $out" >&2
fi
