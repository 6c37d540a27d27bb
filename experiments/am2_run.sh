#!/bin/bash
# One anti-mirror run of the level-step / iterations / wavelength study:
#   am2_run.sh NAME SIZE SEED [wavebrdf design options …]   (writes /tmp/am2/NAME, prints one line)
# The light is given by the options (e.g. --spectral 16 --band-um 0.40 0.70, or --lambda-um 0.55).
name=$1 size=$2 seed=$3; shift 3
mkdir -p /tmp/am2; rm -rf /tmp/am2/$name
/usr/bin/time -f "%U" -o /tmp/am2/$name.user nice ${WAVEBRDF:-build/bin/wavebrdf} design --target anti-mirror --size $size \
  --texel-um 0.5 --levels 8 --height-range-um 2 --seed $seed --no-plots --quiet --threads ${THREADS:-2} \
  --out /tmp/am2/$name "$@" && \
  echo "$name [$*] user $(cat /tmp/am2/$name.user)s: $(/usr/bin/python3 experiments/am_summary.py /tmp/am2/$name/design.json | cut -d: -f2-)"
