#!/usr/bin/env bash
# The recovery benchmark of docs/recovery.md, run through `wavebrdf recover` itself: fresh
# isotropic truths (correlation 4 texels, heights ±1 µm = 2 µm peak to valley, texel 2 µm),
# seeds never used while developing (2001–2003), the planner's acquisition, without noise and
# with 10⁴ photons per slice; the thesis's method on the same data; and the measured-fast
# acquisition (48×48 slices). One line per run in out/recovery/summary.csv.
#   bash experiments/recovery.sh [targets|fast|thesis|all]
set -euo pipefail
cd "$(dirname "$0")/.."
[ -x build/bin/wavebrdf ] || bash scripts/setup.sh
W=build/bin/wavebrdf
OUT=${OUT:-out/recovery}
mkdir -p "$OUT"
SUMMARY="$OUT/summary.csv"
[ -f "$SUMMARY" ] || echo "run,size,seed,noise,method,observations,resolution,height_rel_rmse,seconds" > "$SUMMARY"

run() {  # name size seed noise method [extra options...]
    local name=$1 size=$2 seed=$3 noise=$4 method=$5
    shift 5
    local dir="$OUT/$name"
    $W recover --size "$size" --seed "$seed" --noise "$noise" --method "$method" --out "$dir" --quiet "$@"
    local obs res err secs
    obs=$(/usr/bin/python3 -c "import json; print(json.load(open('$dir/run.json'))['observations'])")
    res=$(/usr/bin/python3 -c "import numpy as np; print(np.load('$dir/reference.npy').shape[0])")
    err=$(tail -1 "$dir/metrics.csv" | awk -F, '{print $5}')
    secs=$(tail -1 "$dir/metrics.csv" | awk -F, '{print $4}')
    echo "$name,$size,$seed,$noise,$method,$obs,$res,$err,$secs" | tee -a "$SUMMARY"
}

targets() {
    for size in 32 64; do
        for seed in 2001 2002 2003; do
            [ "$size" = 64 ] && [ "$seed" = 2003 ] && continue
            run "pipeline_${size}_${seed}" $size $seed none pipeline
            run "pipeline_${size}_${seed}_photons1e4" $size $seed poisson:1e4 pipeline
        done
    done
}
fast() {
    for size in 32 64; do
        for seed in 2001 2002; do
            run "fast_${size}_${seed}" $size $seed none pipeline --resolution 48
            run "fast_${size}_${seed}_photons1e4" $size $seed poisson:1e4 pipeline --resolution 48
        done
    done
}
thesis() {
    for size in 32 64; do
        run "thesis_${size}_2001" $size 2001 none thesis --epochs 5000 --no-plots
        run "thesis_${size}_2001_photons1e4" $size 2001 poisson:1e4 thesis --epochs 5000 --no-plots
    done
}

case "${1:-all}" in
    targets) targets ;;
    fast) fast ;;
    thesis) thesis ;;
    all) targets; fast; thesis ;;
    *) echo "usage: $0 [targets|fast|thesis|all]" >&2; exit 2 ;;
esac
