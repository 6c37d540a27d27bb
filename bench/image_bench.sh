#!/usr/bin/env bash
# Camera-image speed (results: bench/results/2026-11-29-image.md): the README demo's scratched
# surface (512², 1 µm texels) on a 6 mm plate, one point light, 16 wavelengths, every footprint
# σ_p = 10 µm, OHS, pruning bound 1e-3.
#   speed      the 1024² image: wall and CPU time, pixel-kernel-wavelength terms per second
#   accuracy   a 256² image of the same scene pruned (1e-3, at the chosen precision) and unpruned
#              (double): the largest difference,
#              relative to the image's peak and to each pixel's own bound
# Usage: bash bench/image_bench.sh [--build DIR] [--resolution N] [--threads T] [--plane-size-um W]
#            [--precision double|float]
# (the default 6 mm plate fills about half the frame; 20000 fills all of it)
# Needs a Release build of wavebrdf_cli and wavebrdf_python.
set -euo pipefail
cd "$(dirname "$0")/.."
build=build
resolution=1024
threads=2
plane=6000
precision=double
while [ $# -gt 0 ]; do
    case "$1" in
        --build) build=$2; shift 2 ;;
        --resolution) resolution=$2; shift 2 ;;
        --threads) threads=$2; shift 2 ;;
        --plane-size-um) plane=$2; shift 2 ;;
        --precision) precision=$2; shift 2 ;;
        *) echo "unknown option $1" >&2; exit 2 ;;
    esac
done
W=$build/bin/wavebrdf
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
$W heightfield --type scratched --size 512 --seed 7 --scratches 60 --scratch-depth-um 0.08 \
    --scratch-width-um 2 --correlation-um 4 --out "$dir/scratched.exr" > /dev/null
scene=(--heightfield "$dir/scratched.exr" --plane-size-um "$plane" --camera -6000,0,9000 --look-at 0,0,0
       --fov-deg 40 --point-light 5000,1500,7000 --spectral 16 --sigma-p-um 10 --quiet --threads "$threads")

# The processor and the load: the project's machines are not always the same CPU (an AMD EPYC on
# 2026-11-29, an Intel Xeon on 2026-11-30, where the 1024² run took 1.5x its CPU time), so figures compare only
# with the same model name.
echo "== machine: $(sed -n 's/^model name[[:space:]]*: //p' /proc/cpuinfo | head -1), $(nproc) CPUs; load $(cut -d' ' -f1-3 /proc/loadavg)"
echo "== speed: ${resolution}² image, $threads threads"
/usr/bin/time -f "wall %e s, user %U s, sys %S s, max RSS %M kB" \
    "$W" image "${scene[@]}" --resolution "$resolution" --prune-tolerance 1e-3 --precision "$precision" --out "$dir/speed.exr" \
    --png "$dir/speed.png" 2> "$dir/time.txt" || { cat "$dir/time.txt"; exit 1; }
cat "$dir/time.txt"
wall=$(sed -n 's/^wall \([0-9.]*\) s.*/\1/p' "$dir/time.txt")
user=$(sed -n 's/.*user \([0-9.]*\) s.*/\1/p' "$dir/time.txt")

echo "== accuracy: 256², pruned (1e-3) at $precision precision against unpruned double"
"$W" image "${scene[@]}" --resolution 256 --prune-tolerance 1e-3 --precision "$precision" --out "$dir/pruned.exr"
"$W" image "${scene[@]}" --resolution 256 --prune-tolerance 0 --precision double --out "$dir/full.exr"

PYTHONPATH=$build/python /usr/bin/python3 - "$dir" "$resolution" "$wall" "$user" <<'EOF'
import sys
import numpy as np
import wavebrdf as wb
d, n, wall, user = sys.argv[1], int(sys.argv[2]), float(sys.argv[3]), float(sys.argv[4])
image, _ = wb.read_slice(d + "/speed.exr")
on = int((np.asarray(image).sum(axis=2) > 0).sum())
kernels = len(wb.GaborRep(wb.Heightfield.from_exr(d + "/scratched.exr"), x_um=256.0, y_um=256.0, sigma_p_um=10.0))
terms = on * kernels * 16
print("pixels on the plate %d of %d, kernels per footprint %d" % (on, n * n, kernels))
print("terms (pixel x kernel x wavelength, before pruning) %.3g: %.3g per s wall, %.3g per CPU-s"
      % (terms, terms / wall, terms / user))
full = np.asarray(wb.read_slice(d + "/full.exr")[0], dtype=np.float64)
pruned = np.asarray(wb.read_slice(d + "/pruned.exr")[0], dtype=np.float64)
diff = np.abs(full - pruned)
peak = full.max()
print("256²: largest |pruned - unpruned| %.3g = %.3g of the image's peak; median pixel %.3g"
      % (diff.max(), diff.max() / peak, np.median(full)))
lit = full > 1e-3 * peak
print("pixels above 1e-3 of the peak: largest relative difference %.3g" % (diff[lit] / full[lit]).max())
EOF
