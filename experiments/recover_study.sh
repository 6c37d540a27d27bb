#!/usr/bin/env bash
# The recovery study of issue 5 (targets, baselines, where it fails), with fixed seeds on fresh
# isotropic surfaces (correlation 4 texels, max |H| = 1 um). One RESULT / BASELINE line per run
# in $OUT/results.txt (default out/recover_study). Needs the recover_study program
# (experiments/recover_study.cpp; $BIN, default build/bin/recover_study).
#   bash experiments/recover_study.sh [targets|baselines|failures|all]
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=${BIN:-build/bin/recover_study}
OUT=${OUT:-out/recover_study}
mkdir -p "$OUT"
RESULTS="$OUT/results.txt"
# The acquisition of every run unless a case changes it: texel 2 um, sigma_p 3 um, a raster of
# 5.33 um (70 % linear overlap of 6 sigma_p windows) jittered by +-20 %, 48x48 slices (u step
# 1/(12 um): a third of the intensity's Nyquist rate 1/(2D), D = 6 sigma_p, and enough),
# wavelengths 0.5, 0.55, 0.65 um.
BASE="texel_um=2 corr_texels=4 max_height_um=1 sigma_p_um=3 step_um=5.3 jitter=0.2 resolution=48 lambdas=0.5,0.55,0.65"
run() {  # name args...
    local name=$1
    shift
    echo "== $name: $*" | tee -a "$RESULTS"
    "$BIN" $BASE "$@" quiet=1 | tee -a "$RESULTS"
}

targets() {
    for seed in 11 12 13; do run "target 32x32 seed $seed" size=32 seed=$seed; done
    for seed in 11 12 13; do run "target 64x64 seed $seed" size=64 seed=$seed; done
    run "target 32x32 seed 11, 96x96 slices" size=32 seed=11 resolution=96
    run "target 64x64 seed 11, 96x96 slices" size=64 seed=11 resolution=96
}
baselines() {
    # Same data as "target 32x32 seed 11"; the recovery itself is skipped (0 iterations would
    # still run it, so the baselines are printed after a normal recovery).
    run "baselines 32x32 seed 11" size=32 seed=11 baseline_epochs=5000 direct_iters=100
}
failures() {
    for step in 8 9 10; do run "sparse: step $step um" size=32 seed=11 step_um=$step; done
    for n in 32 24; do run "coarse slices: n=$n" size=32 seed=11 resolution=$n; done
    run "one wavelength" size=32 seed=11 lambdas=0.5
    run "two wavelengths" size=32 seed=11 lambdas=0.5,0.65
    for h in 2 4; do run "heights +-$h um" size=32 seed=11 max_height_um=$h; done
    for c in 3 2; do run "correlation $c texels" size=32 seed=11 corr_texels=$c; done
}

case "${1:-all}" in
    targets) targets ;;
    baselines) baselines ;;
    failures) failures ;;
    all) targets; baselines; failures ;;
    *) echo "usage: $0 [targets|baselines|failures|all]" >&2; exit 2 ;;
esac
