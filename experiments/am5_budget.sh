#!/bin/bash
# The anti-mirror acceptance's design (white light 0.40-0.70 um at 16 samples, 8 levels within 2 um,
# normal light) at larger iteration budgets than the defaults (200 relaxed iterations, 60 discrete
# passes). am5_budget.sh WAVEBRDF OUTDIR THREADS; each run's design.json holds its exact metrics.
set -eu
B=$1 OUT=$2 TH=$3
run() { n=$1 s=$2 it=$3 rp=$4; shift 4
  /usr/bin/time -f "$n %U user %e wall %M KB" "$B" design --target anti-mirror --size "$s" --texel-um 0.5 \
    --levels 8 --height-range-um 2 --spectral 16 --band-um 0.40 0.70 --iterations "$it" --refine-passes "$rp" \
    "$@" --no-plots --quiet --threads "$TH" --out "$OUT/$n"; }
run d153_256 256 1000 200 --seed 2611298
run e165_256 256 1000 200 --seed 2611298 --level-step-um 0.165
run e165_128_1k 128 1000 200 --seed 3 --level-step-um 0.165
run e165_128_4k 128 4000 800 --seed 3 --level-step-um 0.165
# one wavelength, 128^2: 0.55 um seed 5 at the defaults, 5x the budget, a shallow step; seed 7; 0.45 um
one() { n=$1 lam=$2; shift 2; "$B" design --target anti-mirror --size 128 --texel-um 0.5 --levels 8 --height-range-um 2 \
    --lambda-um "$lam" "$@" --no-plots --quiet --threads "$TH" --out "$OUT/$n"; }
one s55 0.55 --seed 5
one s55_it1 0.55 --seed 5 --iterations 1000 --refine-passes 200
one s55_shallow 0.55 --seed 5 --level-step-um 0.0356
one s55_s7 0.55 --seed 7
one s45 0.45 --seed 5
# larger equal steps on the acceptance tile (the mirror cone is lost above ~0.17 um)
run f180 256 1000 200 --seed 2611298 --level-step-um 0.18
run f200 256 1000 200 --seed 2611298 --level-step-um 0.20
run f240 256 1000 200 --seed 2611298 --level-step-um 0.24
