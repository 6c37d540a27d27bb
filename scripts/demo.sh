#!/usr/bin/env bash
# The main job on a built-in default: sets up, builds, generates a scratched metal
# heightfield and renders its spectral BRDF slice. Results land in out/demo/.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
mkdir -p out/demo
W=build/bin/wavebrdf
$W heightfield --type scratched --size 512 --seed 7 --scratches 60 --scratch-depth-um 0.08 \
    --scratch-width-um 2 --correlation-um 4 --out out/demo/scratched.exr
$W render --heightfield out/demo/scratched.exr --x-um 256 --y-um 256 --sigma-p-um 20 \
    --spectral 12 --resolution 384 --light-x 0 --light-y 0 --exposure -4 --reinhard \
    --out out/demo/slice.exr --png out/demo/slice.png
echo "demo: wrote out/demo/scratched.{exr,png} and out/demo/slice.{exr,png}"
