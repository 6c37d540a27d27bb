#!/usr/bin/env bash
# Times `wavebrdf genbrdf` against the reference program genBrdf (Yan et al. 2018's public
# release, built separately by the user; none of its code is in this repository) on the same
# inputs in the same run. Usage:
#   GENBRDF=/path/to/genBrdf bash bench/compare_genbrdf.sh [runs]
# Without GENBRDF only wavebrdf is timed. Prints the median wall time of each case.
set -euo pipefail
cd "$(dirname "$0")/.."
runs=${1:-5}
W=build/bin/wavebrdf
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
$W heightfield --type isotropic --size 1024 --rms-height-um 0.05 --correlation-um 4 --seed 1 \
    --out "$work/iso1024.exr" --no-png --quiet

median() { sort -g | awk '{a[NR]=$1} END {print (NR % 2) ? a[(NR+1)/2] : (a[NR/2] + a[NR/2+1]) / 2}'; }
time_runs() {  # program args...: one warm-up, then $runs timed runs
    "$@" >/dev/null 2>&1
    for _ in $(seq "$runs"); do
        local s e
        s=$(date +%s.%N); "$@" >/dev/null 2>&1; e=$(date +%s.%N)
        echo "$e - $s" | bc
    done | median
}

printf "%-34s %12s %12s %8s\n" case "genBrdf [s]" "wavebrdf [s]" ratio
for args in "-r 128 -l 0 -p 10" "-r 256 -l 0.5 -p 10" "-r 128 -l 0.5 -p 10 -d GHS"; do
    ours=$(time_runs $W genbrdf -i "$work/iso1024.exr" -o "$work/ours.exr" $args --quiet)
    if [ -n "${GENBRDF:-}" ]; then
        ref=$(time_runs "$GENBRDF" -i "$work/iso1024.exr" -o "$work/ref.exr" $args)
        ratio=$(echo "scale=1; $ref / $ours" | bc)
    else
        ref="-"; ratio="-"
    fi
    printf "%-34s %12s %12s %8s\n" "$args" "$ref" "$ours" "$ratio"
done
