#!/usr/bin/env bash
# Results-unchanged check for refactors of the design run: small designs over its routes (anti-
# mirror with fabrication errors in the loop, a pattern, a colour with its mixture bound and view
# survey, a grayscale relief), each reduced to the md5 of its heights, pictures, metrics.csv and
# design.json without its timings. Usage: experiments/design_baseline.sh [BIN] [OUT_TABLE]
# (BIN default build/bin/wavebrdf). Identical tables mean identical outputs on every route.
set -euo pipefail
bin=${1:-build/bin/wavebrdf}
table=${2:-/dev/stdout}
here=$(cd "$(dirname "$0")/.." && pwd)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
small="--size 32 --iterations 40 --refine-passes 10 --seed 3 --threads 2 --quiet --no-plots"
routes=(
  "anti-mirror|--target anti-mirror --spectral 4 --fabrication-error scale:5%,blur:0.3um"
  "pattern|--target pattern:$here/fuzz/corpus/png_picture/grey8_4x4.png"
  "colour|--target colour:#3060c0 --spectral 8"
  "grayscale|--target anti-mirror --min-feature-um 2"
)
lines=()
for r in "${routes[@]}"; do
  name=${r%%|*}
  args=${r#*|}
  out="$work/$name"
  # shellcheck disable=SC2086
  nice "$bin" design $args $small --out "$out" > "$work/$name.log" 2>&1 ||
    { echo "$name FAILED"; cat "$work/$name.log"; exit 1; }
  json=$(/usr/bin/python3 - "$out/design.json" <<'PY'
import json, sys
j = json.load(open(sys.argv[1]))
j.pop("timings_s", None)
j.get("view_survey", {}).pop("seconds", None)
print(json.dumps(j, sort_keys=True))
PY
)
  sums=$(cd "$out" && md5sum heights.exr target.exr far_field.exr metrics.csv | cut -c1-8 | tr '\n' ' ')
  lines+=("$(printf '%-12s json:%s files:%s' "$name" "$(md5sum <<< "$json" | cut -c1-32)" "$sums")")
  echo "${lines[-1]}" >&2
done
printf '%s\n' "${lines[@]}" > "$table"
