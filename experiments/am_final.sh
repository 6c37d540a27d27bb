#!/bin/bash
# The acceptance's anti-mirror (256², 8 levels within 2 µm, 16 wavelengths 0.40–0.70 µm, normal
# light) at the defaults: am_final.sh SEED; writes /tmp/am/final_SEED and times it.
seed=$1
rm -rf /tmp/am/final_$seed
/usr/bin/time -v nice build/bin/wavebrdf design --target anti-mirror --size 256 --texel-um 0.5 --levels 8 \
  --height-range-um 2 --spectral 16 --band-um 0.40 0.70 --seed $seed --no-plots --quiet --threads 2 \
  --out /tmp/am/final_$seed 2> /tmp/am/final_$seed.time
/usr/bin/python3 experiments/am_summary.py /tmp/am/final_$seed/design.json
grep -E "User time|Elapsed|Maximum resident" /tmp/am/final_$seed.time
