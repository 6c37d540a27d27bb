#!/bin/bash
# The anti-mirror with its constraints as limits (augmented Lagrangian, docs/design.md) over
# 0.40-0.70 um (16 samples, 8 levels within 2 um, normal light, default budget), one design per
# level step (the default rule and 0.165 um). am7_multipliers.sh WAVEBRDF OUTDIR SIZE SEED...
# The rho and constraint-form variants need a study build with experiments/am7_study.patch applied
# (WB_AM_RHO=R sets rho, WB_AM_LINEAR=1 takes g = x/aim - 1 instead of ln(x/aim)); the previous
# loss is main at f92e6ab. Score independently: PYTHONPATH=build/python experiments/am5_breakdown.py OUT/*/heights.exr
set -eu
B=$1 OUT=$2 S=$3; shift 3
for SEED in "$@"; do
  for STEP in rule 0.165; do
    extra=(); [ "$STEP" != rule ] && extra=(--level-step-um "$STEP")
    OMP_NUM_THREADS=1 nice -n 10 "$B" design --target anti-mirror --size "$S" --texel-um 0.5 --levels 8 \
      --height-range-um 2 --spectral 16 --band-um 0.40,0.70 "${extra[@]}" --seed "$SEED" --threads 1 \
      --no-plots --quiet --out "$OUT/s$SEED-$STEP"
  done
done
