#!/usr/bin/env bash
# Results-unchanged check for refactors of the recovery: short recoveries over every route,
# each reduced to the md5 of its estimate (estimate_height.npy), of its metrics trajectory
# (metrics.csv without the seconds column) and, where written, of uncertainty.exr.
# Usage: experiments/stages_baseline.sh [BIN] [OUT_TABLE]  (BIN default build/bin/wavebrdf;
# ONLY=route,route runs those routes only). Compare two tables without their last column (wall
# seconds): cut -d' ' -f1-5 | diff; identical tables mean identical bits on every route.
set -euo pipefail
bin=${1:-build/bin/wavebrdf}
table=${2:-/dev/stdout}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMP_WAIT_POLICY=passive

routes=(
  "default|--size 16"
  "noise-poisson|--size 16 --noise poisson:2000"
  "calibrate-all|--size 16 --calibrate all --simulate-position-error-texels 0.5 --simulate-exposure 0.8,1.25 --position-passes 2"
  "white-light|--size 16 --spectral 4"
  "pm4um-oblique|--size 16 --height-range-um 8"
  "ghs-proxy|--size 16 --model GHS"
  "tiled-field|--size 32 --field-tile-threshold 16 --field-tile-core 16 --refine-iterations 10"
  "mpi-2|--size 16"
  "uncertainty|--size 16 --noise poisson:2000 --uncertainty"
)
lines=()
for r in "${routes[@]}"; do
  name=${r%%|*}
  args=${r#*|}
  [[ -z ${ONLY:-} || ,$ONLY, == *,$name,* ]] || continue
  out="$work/$name"
  start=$(date +%s)
  if [[ $name == mpi-* ]]; then
    # shellcheck disable=SC2086
    nice mpiexec -n 2 --oversubscribe --bind-to none -x OMP_NUM_THREADS=1 -x OMP_WAIT_POLICY \
      -x OMPI_MCA_mpi_yield_when_idle=1 "$bin" recover $args --seed 1 --no-plots --quiet \
      --out "$out" > "$work/$name.log" 2>&1 || { echo "$name FAILED"; cat "$work/$name.log"; exit 1; }
  else
    # shellcheck disable=SC2086
    nice "$bin" recover $args --seed 1 --threads 2 --no-plots --quiet --out "$out" \
      > "$work/$name.log" 2>&1 || { echo "$name FAILED"; cat "$work/$name.log"; exit 1; }
  fi
  est=$(md5sum < "$out/estimate_height.npy" | cut -c1-32)
  met=$(cut -d, -f1-3,5- "$out/metrics.csv" | md5sum | cut -c1-32)
  last=$(tail -1 "$out/metrics.csv" | cut -d, -f1,3,5)
  unc=-
  [[ -f $out/uncertainty.exr ]] && unc=$(md5sum < "$out/uncertainty.exr" | cut -c1-32)
  lines+=("$(printf '%-14s %s %s %s %s %ss' "$name" "$est" "$met" "$unc" "$last" \
    "$(( $(date +%s) - start ))")")
  echo "${lines[-1]}" >&2
done
{
  echo "# route estimate_md5 metrics_md5 uncertainty_md5 last_stage,loss,height_rel_rmse wall"
  printf '%s\n' "${lines[@]}"
} > "$table"
