#!/usr/bin/env bash
# The thesis's chapter-5 experiments, one command each:
#   bash experiments/run.sh e1          16×16 heights, 32×32 slice, flat start, Adam, CMSLE ε = 1
#   bash experiments/run.sh e2          the same with 16×16 and 64×64 slices
#   bash experiments/run.sh e3          truth + 10 % noise, lr 0.0015, CMSLE ε = 0.01, 1000 epochs,
#                                       random positions
#   bash experiments/run.sh roughness   E1 and E3 over generated truths of increasing roughness
#   bash experiments/run.sh all
# Results land in out/experiments/<name>/ (metrics.csv, report.png, curves.png, ...); a summary
# line per run is appended to out/experiments/summary.csv.
set -euo pipefail
cd "$(dirname "$0")/.."
[ -x build/bin/wavebrdf ] || bash scripts/setup.sh
W=build/bin/wavebrdf
OUT=out/experiments
mkdir -p "$OUT"
SUMMARY="$OUT/summary.csv"
[ -f "$SUMMARY" ] || echo "run,epochs,loss_ratio,brdf_mse_ratio,height_mse_ratio,seconds" > "$SUMMARY"

# Ratios of the last epoch's metrics to epoch 0's, from metrics.csv.
summarise() {
    local name=$1 dir=$2
    awk -F, -v name="$name" 'NR==2 {l0=$2; b0=$3; h0=$8} END {printf "%s,%d,%.6g,%.6g,%.6g,%.1f\n", name, $1, $2/l0, $3/b0, ($8=="nan"?"nan":$8/h0), $9}' \
        "$dir/metrics.csv" | tee -a "$SUMMARY"
}

truth() {  # name rms_height_um: a 16×16 isotropic truth, correlation 2 µm, seed 1
    $W heightfield --type isotropic --size 16 --rms-height-um "$2" --correlation-um 2 --seed 1 \
        --out "$OUT/$1.exr" --quiet
}

e1() { truth truth_e1 0.35; $W invert --truth "$OUT/truth_e1.exr" --out "$OUT/e1" --quiet; summarise e1 "$OUT/e1"; }
e2() {
    truth truth_e1 0.35
    for n in 16 64; do
        $W invert --truth "$OUT/truth_e1.exr" --resolution $n --out "$OUT/e2_$n" --quiet
        summarise "e2_$n" "$OUT/e2_$n"
    done
}
e3() {
    truth truth_e1 0.35
    $W invert --truth "$OUT/truth_e1.exr" --init noisy:0.1 --lr 0.0015 --loss cmsle:0.01 --epochs 1000 \
        --positions random --snapshots 0,10,50,200,1000 --out "$OUT/e3" --quiet
    summarise e3 "$OUT/e3"
}
roughness() {
    for rms in 0.05 0.1 0.2 0.35 0.5; do
        truth "truth_rms$rms" "$rms"
        $W invert --truth "$OUT/truth_rms$rms.exr" --out "$OUT/e1_rms$rms" --quiet --no-plots
        summarise "e1_rms$rms" "$OUT/e1_rms$rms"
        $W invert --truth "$OUT/truth_rms$rms.exr" --init noisy:0.1 --lr 0.0015 --loss cmsle:0.01 \
            --epochs 1000 --positions random --out "$OUT/e3_rms$rms" --quiet --no-plots
        summarise "e3_rms$rms" "$OUT/e3_rms$rms"
    done
}

case "${1:-all}" in
    e1) e1 ;;
    e2) e2 ;;
    e3) e3 ;;
    roughness) roughness ;;
    all) e1; e2; e3; roughness ;;
    *) echo "usage: bash experiments/run.sh e1|e2|e3|roughness|all" >&2; exit 2 ;;
esac
