#!/usr/bin/env bash
# The main job on a built-in default: sets up and builds only the CLI, then
#  1. renders the spectral BRDF slice of a generated scratched surface, and a camera picture of
#     a plate carrying it (docs/image.md) → out/demo/{scratched.png, slice.png, image.png};
#  2. builds the Python module (the report plotter) and runs the inverse renderer on the
#     thesis's first experiment (a generated 16×16 truth, normal incidence, 32×32 spectral
#     slice, flat start, Adam, CMSLE ε = 1, 300 epochs)
#     → out/invert/{report.png, curves.png, metrics.csv, estimate.exr, ...}
# The pictures come first: they need only the CLI, so they do not wait for the module's build.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh --demo
W=build/bin/wavebrdf
mkdir -p out/demo
$W heightfield --type scratched --size 512 --seed 7 --scratches 60 --scratch-depth-um 0.08 \
    --scratch-width-um 2 --correlation-um 4 --out out/demo/scratched.exr
$W render --heightfield out/demo/scratched.exr --x-um 256 --y-um 256 --sigma-p-um 20 \
    --spectral 12 --resolution 384 --exposure -4 --reinhard \
    --out out/demo/slice.exr --png out/demo/slice.png
$W image --heightfield out/demo/scratched.exr --plane-size-um 6000 --camera -6000,0,9000 --look-at 0,0,0 \
    --fov-deg 40 --resolution 256 --point-light 5000,1500,7000 --spectral 12 --sigma-p-um 10 \
    --exposure 2 --out out/demo/image.exr --png out/demo/image.png
cmake --build build -j"$(nproc)" --target wavebrdf_python
$W invert --out out/invert
echo "demo: see out/demo/slice.png, out/demo/image.png, out/invert/report.png and out/invert/curves.png"
