#!/usr/bin/env bash
# The BRDF table benchmark (bench/results/2026-11-23-table.md): `wavebrdf table` of 32x32 lights
# x 64x64 slices of a generated 256x256 isotropic surface (seed 1, texel 1 um, rms height
# 0.1 um), sigma_p 10 um, OHS, 3 wavelengths (--spectral 3), timed as a whole process (median
# of RUNS, default 3). Usage: bench/table_bench.sh [BUILD_DIR] [WORK_DIR]
set -euo pipefail
build=${1:-build}
work=${2:-$(mktemp -d)}
runs=${RUNS:-3}
cli=$(cd "$build/bin" && pwd)/wavebrdf
mkdir -p "$work"
cd "$work"
"$cli" heightfield --type isotropic --size 256 --seed 1 --out iso256.exr --no-png --quiet
times=()
for ((k = 0; k < runs; ++k)); do
  start=$(date +%s.%N)
  "$cli" table --heightfield iso256.exr --sigma-p-um 10 --x-um 128 --y-um 128 --spectral 3 --resolution 64 \
    --lights 32x32 --max-light-sin 0.9 --out table.exr --png table.png --quiet
  end=$(date +%s.%N)
  times+=("$(echo "$end - $start" | bc -l)")
  echo "run $((k + 1)): ${times[-1]} s"
done
printf '%s\n' "${times[@]}" | sort -g | awk '{a[NR] = $1} END {print "median: " a[int((NR + 1) / 2)] " s"}'
echo "file: $(stat -c %s table.exr) bytes table.exr, $(stat -c %s table.png) bytes table.png (in $work)"
