#!/bin/bash
# One anti-mirror study run: am_run.sh NAME SIZE SEED ITER [ENV=VALUE ...]; writes /tmp/am/NAME.
name=$1 size=$2 seed=$3 iter=$4; shift 4
rm -rf /tmp/am/$name
env "$@" nice build/bin/wavebrdf design --target anti-mirror --size $size --texel-um 0.5 --levels 8 \
  --height-range-um 2 --spectral 16 --band-um 0.40 0.70 --seed $seed --iterations $iter ${AM_EXTRA:-} --no-plots --quiet \
  --threads 2 --out /tmp/am/$name && /usr/bin/python3 experiments/am_summary.py /tmp/am/$name/design.json
