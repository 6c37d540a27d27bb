#!/bin/bash
# The anti-mirror's level step as a design variable (docs/design.md) against fixed steps, over
# 0.40-0.70 um (16 samples, 8 levels within 2 um, normal light, default budget unless EXTRA says).
# am8_level_step.sh WAVEBRDF OUTDIR SIZE "STEPS" SEED... ; STEPS: "free" (no --level-step-um: the
# loop moves the step) and/or fixed steps in um, e.g. "free 0.165". One line per design: step
# (final), region mean (worst), uniformity worst, cone worst, repair blocks, CPU-s.
set -eu
B=$1 OUT=$2 S=$3 STEPS=$4; shift 4
for SEED in "$@"; do
  for STEP in $STEPS; do
    extra=(); [ "$STEP" != free ] && extra=(--level-step-um "$STEP")
    D="$OUT/s$SEED-$STEP"
    rm -rf "$D"
    /usr/bin/time -f "%U" -o "$D.time" env OMP_NUM_THREADS=1 nice -n 10 "$B" design --target anti-mirror --size "$S" \
      --texel-um 0.5 --levels 8 --height-range-um 2 --spectral 16 --band-um 0.40,0.70 "${extra[@]}" ${EXTRA:-} \
      --seed "$SEED" --threads 1 --no-plots --quiet --out "$D"
    python3 - "$D/design.json" "$SEED" "$STEP" "$(cat "$D.time")" <<'PY'
import json, sys
j = json.load(open(sys.argv[1])); e = j["metrics"]["exact"]
print(f"seed {sys.argv[2]} {sys.argv[3]:>5}: step {j['levels_um'][1]:.4f} region {100*e['region_fraction_mean']:.1f} % "
      f"({100*e['region_fraction_worst']:.1f}) u {e['uniformity_worst']:.4f} cone {100*e['specular_fraction_worst']:.3f} % "
      f"repairs {j['constraint_loop']['repair_blocks']} cpu {sys.argv[4]} s")
PY
  done
done
