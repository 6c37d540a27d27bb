#!/bin/bash
# What each of the anti-mirror's constraints costs the design loop over 0.40-0.70 um (16 samples,
# 8 levels on 0.165 um steps within 2 um, normal light, default budget): the acceptance's loss, and
# the same with the uniformity term off, the cone term off, or both. Needs a study build with
# experiments/am6_loss_weights.patch applied (the loss's weights and hinges read from WB_WUNIF,
# WB_UFREE, WB_WCONE, WB_CFREE). am6_constraint_costs.sh WAVEBRDF OUTDIR SIZE SEED
# Score each heights.exr independently: PYTHONPATH=build/python experiments/am3_band.py score OUT/*/heights.exr
set -eu
B=$1 OUT=$2 S=$3 SEED=$4
run() { n=$1; shift
  env "$@" nice -n 10 "$B" design --target anti-mirror --size "$S" --texel-um 0.5 --levels 8 --height-range-um 2 \
    --spectral 16 --band-um 0.40 0.70 --seed "$SEED" --level-step-um 0.165 --no-plots --quiet --threads 2 --out "$OUT/$n"; }
run full
run no_uniformity WB_WUNIF=0
run no_cone WB_WCONE=0
run region_only WB_WUNIF=0 WB_WCONE=0
run ufree_024 WB_UFREE=0.24
run cone_hinge WB_CFREE=0.0015 WB_WCONE=1000
run both_hinges WB_UFREE=0.24 WB_CFREE=0.0015 WB_WCONE=1000
run weights_half WB_WCONE=50 WB_WUNIF=10
run weights_quarter WB_WCONE=25 WB_WUNIF=5
