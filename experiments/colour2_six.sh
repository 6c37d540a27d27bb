#!/bin/bash
# The six sRGB primaries and secondaries on the colour acceptance's tile: 128², 0.5 µm texels,
# 16 levels within 2 µm, 16 samples of the slices' white, the mirror direction's cone 0.05.
# Usage: [COLOURS="FF0000 0000FF"] colour2_six.sh SEED OUTDIR [extra design options...]
# Prints one line per colour: Δu′v′, Y, the optimal-colour bound, kirchhoff_total mean, wall time.
set -euo pipefail
seed=$1; out=$2; shift 2
bin=${WAVEBRDF:-build/bin/wavebrdf}
mkdir -p "$out"
for c in ${COLOURS:-FF0000 00FF00 0000FF 00FFFF FF00FF FFFF00}; do
  d="$out/c$c-s$seed"
  rm -rf "$d"
  start=$(date +%s.%N)
  nice "$bin" design --target "colour:#$c" --size 128 --texel-um 0.5 --levels 16 --height-range-um 2 \
      --spectral 16 --seed "$seed" --no-plots --quiet --out "$d" "$@"
  end=$(date +%s.%N)
  /usr/bin/python3 - "$d/design.json" "$c" "$start" "$end" <<'PY'
import json, sys
j = json.load(open(sys.argv[1])); e = j["metrics"]["exact"]; b = j.get("optimal_colour_bound", {})
kt = j["metrics"]["kirchhoff_total"]
s = j.get("view_survey")
m = j.get("mixture_bound")
mb = "" if not m else (f" mix {100*m['y_at_target']:.2f}%" + ("" if m["delta_uv_at_min_y"] is None else f"/duv>={m['delta_uv_at_min_y']:.4f}")
                       + f" one {m['one_mixture']['delta_uv']:.4f}/{100*m['one_mixture']['y']:.2f}%"
                       + f" check n {100*m['design_check']['normalised']['y']:.2f}<={100*m['design_check']['normalised']['bound_y_at_its_chromaticity']:.2f}"
                       + f" a {100*m['design_check']['absolute']['y']:.2f}<={100*m['design_check']['absolute']['bound_y_at_its_chromaticity']:.2f}")
sv = "" if not s else " survey " + "; ".join(f"({v['view'][0]:.1f}) {v['delta_uv']:.4f}/{100*v['luminous_efficiency']:.1f}%" for v in s["views"])
print(f"#{sys.argv[2]} duv {e['delta_uv']:.4f} Y {100*e['luminous_efficiency']:.2f}% bound {100*b.get('y_at_target',0):.1f}%/"
      f"{100*b.get('y_within_delta_uv',0):.1f}% kt {sum(kt)/len(kt):.3f} wall {float(sys.argv[4])-float(sys.argv[3]):.0f}s{mb}{sv}")
PY
done
