#!/usr/bin/python3
"""The OHS forward model in PyTorch with autograd: the baseline for wavebrdf's gradient.

Run: /usr/bin/python3 bench/torch_reference.py [--check] [--cases thesis,256]
                                              [--precisions float32,float64] [--chunks none,1024,128]
(Debian's python3-torch and python3-numpy; no other module; about 4 minutes on 2 cores).
Prints the torch rows of bench/results/2026-11-21-torch-baseline.md.

What is computed
  Exactly the sum of docs/model.md (§10, "The sum as computed") for OHS at one
  wavelength, λ = 0.5 µm, normal incidence:
      I(u) = Σ_k c_k w² exp(−2π²σ²|u + a_k|²) e^{−i[(4π/λ) H_k + 2π u·δ_k]},
      f = c1 |I|²,  c1 = cos θ_o / (λ² cos θ_i),  f = 0 outside the unit disk,
  with s_k by periodic central differences (torch.roll), a_k = 2 s_k / λ, kernels within 3σ_p
  of the footprint (each texel once, at its nearest periodic image), c_k the window weight.
  Loss L = Σ_p W_p f_p with fixed random W (uniform [0, 1), seed 7); gradient by L.backward().

How it is written
  The way a PyTorch user would write it without exploiting the separability that wavebrdf
  uses: one dense (pixels × kernels) tensor per intermediate, pixels outside the disk left
  out, the Gaussian and the phase folded into a single complex exponential, and the weighted
  sum over kernels as a complex matrix-vector product. Everything that depends on the heights,
  and the (pixels × kernels) phase constants 2π u·δ_k, are computed inside the timed call (as
  in wavebrdf, where a query's footprint can change every call); only O(pixels + kernels)
  geometry (kernel indices, offsets, window weights, the u grid, c1) is prepared outside.
  Unchunked ("none"): the largest case (256² heights, 128² slice, 2828 kernels, 12 892 pixels
  in the disk) fits in memory as a whole (peak 3.3 GiB in float64), so nothing forces chunks.
  A chunk of P pixels runs its own forward and backward (gradients accumulate in h.grad;
  exact, since L is a sum over pixels), which bounds the tape at the price of recomputing the
  O(kernels) part per chunk. It is also faster here: the unchunked tensors are too large for
  the allocator to reuse, and every call pays the kernel's page faults on fresh memory. So by
  default each case also runs in chunks of 1024 pixels (about the fastest in float32 of
  64…4096 on the machine of the results file) and of 128 pixels (a tape of a few MiB at about
  the same speed; the fastest in float64). A chunk not smaller than the case's pixel count
  would be the unchunked run again and is skipped.

Cases (footprint at the tile centre, w = 1 µm)
  thesis  16×16 heights, σ_p = 4 µm (all 256 texels are kernels), 32×32 slice
  256     256×256 heights, σ_p = 10 µm (2828 kernels), 128×128 slice
  Heights: Gaussian-correlated periodic noise (rms 0.05 µm, correlation 4 µm) made here, rounded
  to float32 so that an EXR holds them exactly.

Measured per case and precision, each in a fresh subprocess, torch.set_num_threads(2):
  time    median of ≥ 5 forward+backward calls (small cases: as many as fit in 2 s, at most
          200) after the measured first call and one more warm-up
  tape    bytes of the tensors autograd saves for backward (torch.autograd.graph.
          saved_tensors_hooks, each storage counted once), on the first call
  peak    peak RSS (VmHWM, reset through /proc/self/clear_refs) during the first
          forward+backward minus the RSS before it; before it, one gradient of a tiny problem
          (8×8 heights, 8×8 slice) pages in torch's code and starts its threads

--check renders every case's slice with build/bin/wavebrdf render --precision double (the
heights written to an uncompressed float EXR by this script) and compares. The CLI rounds its
slice to float32 before writing the .npy (apps/slice_job.cpp), so float64 must agree pixel by
pixel to within that rounding (2⁻²⁴ relative) plus 1e-10 of the peak; float32 is reported.
Against the library directly (wavebrdf::slice_gradient<double>, a throwaway driver, see the
results file) the float64 slice and gradient agree to ~1e-15 of their peaks.

How the C++ side is measured (the other half of the results table)
  time    build/bin/render_bench --benchmark_filter=gradient_tile --benchmark_repetitions=5
          --benchmark_report_aggregates_only=true --benchmark_min_time=0.5: the median of
          wavebrdf::slice_gradient<float|double> (forward + adjoint, the library's own
          threading on 2 cores) on the same two cases, heights from
          wavebrdf::generate_heightfield (isotropic, rms 0.05 µm, correlation 4 µm, seed 1).
  memory  a throwaway driver (listed in the results file) that generates that heightfield,
          runs one gradient of a tiny problem (as above), resets VmHWM and calls slice_gradient
          once: VmHWM minus the RSS before the call, the same measure as "peak" here.
          Cross-checked with /usr/bin/time -v: peak RSS of the driver with the gradient minus
          that of the same driver stopping after the heights are made.
"""
import argparse
import json
import math
import os
import statistics
import struct
import subprocess
import sys
import tempfile
import time

import numpy as np
import torch

LAMBDA_UM = 0.5
TEXEL_UM = 1.0
VSCALE = 1.0
CASES = {
    "thesis": dict(size=16, sigma_p_um=4.0, resolution=32),
    "256": dict(size=256, sigma_p_um=10.0, resolution=128),
}
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


# --- inputs ---------------------------------------------------------------------------------

def make_heights(size, seed=1, rms_um=0.05, correlation_um=4.0):
    """Periodic Gaussian-correlated heights in texel units, float32-exact (float64 array)."""
    rng = np.random.default_rng(seed)
    f = np.fft.fftfreq(size, d=TEXEL_UM)
    kx, ky = np.meshgrid(f, f, indexing="ij")
    # √PSD of C(r) = exp(−r²/ℓ²): exp(−π²ℓ²|k|²/2)
    filt = np.exp(-0.5 * math.pi ** 2 * correlation_um ** 2 * (kx ** 2 + ky ** 2))
    h = np.fft.ifft2(np.fft.fft2(rng.standard_normal((size, size))) * filt).real
    h -= h.mean()
    h *= rms_um / TEXEL_UM / h.std()
    return h.astype(np.float32).astype(np.float64)


def geometry(size, sigma_p_um, resolution, x_um, y_um):
    """The constant, O(pixels + kernels) part: kernel indices and offsets, window weights
    c_k w², the u grid of the pixels inside the disk and their c1."""
    period = size * TEXEL_UM
    centres = (np.arange(size) + 0.5) * TEXEL_UM

    def offset(centre):
        d = centres - centre
        return d - period * np.floor(d / period + 0.5)  # nearest periodic image

    dx, dy = np.meshgrid(offset(x_um), offset(y_um), indexing="ij")
    d2 = dx ** 2 + dy ** 2
    keep = (d2 <= (3.0 * sigma_p_um) ** 2).reshape(-1)
    idx = np.nonzero(keep)[0]
    weight = (np.exp(-d2 / (2.0 * sigma_p_um ** 2)) / (math.sqrt(math.pi) * sigma_p_um)
              * TEXEL_UM ** 2).reshape(-1)[idx]
    omega = (np.arange(resolution) + 0.5) / resolution * 2.0 - 1.0
    ox, oy = np.meshgrid(omega, omega, indexing="ij")
    inside = (ox ** 2 + oy ** 2 <= 1.0).reshape(-1)
    pix = np.nonzero(inside)[0]
    ox, oy = ox.reshape(-1)[pix], oy.reshape(-1)[pix]
    cos_i = 1.0  # normal incidence, ω_i = 0
    cos_o = np.sqrt(np.abs(1.0 - ox ** 2 - oy ** 2))
    return dict(idx=idx, dx=dx.reshape(-1)[idx], dy=dy.reshape(-1)[idx], weight=weight,
                pix=pix, ux=ox / LAMBDA_UM, uy=oy / LAMBDA_UM,
                c1=cos_o / (LAMBDA_UM ** 2 * cos_i), resolution=resolution)


def to_torch(geo, dtype):
    cdtype = torch.complex128 if dtype == torch.float64 else torch.complex64
    t = {k: torch.as_tensor(v, dtype=dtype) for k, v in geo.items()
         if k in ("dx", "dy", "ux", "uy", "c1")}
    t["weight"] = torch.as_tensor(geo["weight"], dtype=cdtype)
    t["idx"] = torch.as_tensor(geo["idx"], dtype=torch.long)
    t["pix"] = torch.as_tensor(geo["pix"], dtype=torch.long)
    t["resolution"] = geo["resolution"]
    return t


# --- the model ------------------------------------------------------------------------------

def slice_values(h, g, pixels=slice(None)):
    """f at the in-disk pixels `pixels` (a slice of g's pixel list) for heights h (N×N,
    texel units)."""
    gauss = 2.0 * math.pi ** 2 * (0.5 * TEXEL_UM) ** 2           # 2π²σ², σ = w/2
    height = (VSCALE * TEXEL_UM) * h                               # H in µm
    sx = (0.5 * VSCALE) * (torch.roll(h, -1, 0) - torch.roll(h, 1, 0))   # h[i+1] − h[i−1]
    sy = (0.5 * VSCALE) * (torch.roll(h, -1, 1) - torch.roll(h, 1, 1))
    hk = height.reshape(-1)[g["idx"]]                              # (K,)
    ax = (2.0 / LAMBDA_UM) * sx.reshape(-1)[g["idx"]]
    ay = (2.0 / LAMBDA_UM) * sy.reshape(-1)[g["idx"]]
    ux = g["ux"][pixels, None]                                     # (P, 1)
    uy = g["uy"][pixels, None]
    vx = ux + ax                                                   # (P, K)
    vy = uy + ay
    amplitude = -gauss * (vx * vx + vy * vy)
    phase = -(4.0 * math.pi / LAMBDA_UM) * hk - (2.0 * math.pi) * (ux * g["dx"] + uy * g["dy"])
    field = torch.exp(torch.complex(amplitude, phase)) @ g["weight"]   # (P,)
    return g["c1"][pixels] * (field.real ** 2 + field.imag ** 2)


def full_slice(f, g):
    n = g["resolution"]
    out = torch.zeros(n * n, dtype=f.dtype)
    out[g["pix"]] = f
    return out.reshape(n, n)


def gradient(h0, g, w, chunk=None, hooks=None):
    """One forward + backward of L = Σ W f; returns (L, ∂L/∂h). `hooks()`, when given, returns
    a fresh saved_tensors_hooks context per chunk (for measuring the tape)."""
    h = h0.detach().requires_grad_(True)
    count = g["pix"].numel()
    step = count if chunk is None else chunk
    total = 0.0
    for p0 in range(0, count, step):
        sel = slice(p0, min(count, p0 + step))
        if hooks is None:
            loss = (w[sel] * slice_values(h, g, sel)).sum()
        else:
            with hooks():
                loss = (w[sel] * slice_values(h, g, sel)).sum()
        loss.backward()
        total += loss.item()
    return total, h.grad


# --- measurement ----------------------------------------------------------------------------

def status_kb(key):
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(key):
                return int(line.split()[1])
    return -1


def worker(case, precision, chunk):
    torch.set_num_threads(2)
    dtype = torch.float64 if precision == "float64" else torch.float32
    c = CASES[case]
    geo = geometry(c["size"], c["sigma_p_um"], c["resolution"],
                   0.5 * c["size"] * TEXEL_UM, 0.5 * c["size"] * TEXEL_UM)
    g = to_torch(geo, dtype)
    h = torch.as_tensor(make_heights(c["size"]), dtype=dtype)
    w = torch.as_tensor(np.random.default_rng(7).random(len(geo["pix"])), dtype=dtype)

    # First call: tape (the largest chunk's, when chunked) and peak RSS.
    tapes = []

    def hooks():
        saved = {}
        tapes.append(saved)

        def pack(t):
            s = t.untyped_storage() if hasattr(t, "untyped_storage") else t.storage()
            key = (s.data_ptr(), t.dtype)  # each storage once (x * x saves x twice)
            saved[key] = max(saved.get(key, 0), s.nbytes())
            return t

        return torch.autograd.graph.saved_tensors_hooks(pack, lambda t: t)

    # Page in torch's code and start its threads on a tiny problem first, so that the peak
    # below is the gradient's memory, not the first use of the library.
    tiny = to_torch(geometry(8, 2.0, 8, 4.0, 4.0), dtype)
    gradient(torch.as_tensor(make_heights(8), dtype=dtype), tiny,
             torch.ones(tiny["pix"].numel(), dtype=dtype), 16 if chunk else None, hooks)
    tapes.clear()
    with open("/proc/self/clear_refs", "w") as f:
        f.write("5")  # reset VmHWM to the current RSS
    rss0 = status_kb("VmRSS:")
    gradient(h, g, w, chunk, hooks)
    peak_kb = status_kb("VmHWM:") - rss0
    tape = max(sum(saved.values()) for saved in tapes)

    gradient(h, g, w, chunk)  # warm-up
    times = []
    t_start = time.perf_counter()
    while len(times) < 5 or (time.perf_counter() - t_start < 2.0 and len(times) < 200):
        t0 = time.perf_counter()
        gradient(h, g, w, chunk)
        times.append(time.perf_counter() - t0)
    print(json.dumps(dict(case=case, precision=precision, chunk=chunk,
                          kernels=len(geo["idx"]), pixels=len(geo["pix"]),
                          median_s=statistics.median(times), min_s=min(times), runs=len(times),
                          tape_bytes=tape, peak_rss_bytes=peak_kb * 1024,
                          torch=torch.__version__, threads=torch.get_num_threads())))


def fmt_time(s):
    return f"{s * 1e3:.1f} ms" if s < 1.0 else f"{s:.2f} s"


def fmt_bytes(b):
    return f"{b / 2 ** 20:.1f} MiB" if b < 2 ** 30 else f"{b / 2 ** 30:.2f} GiB"


# --- check against wavebrdf -----------------------------------------------------------------

def write_exr(path, h):
    """Single-channel (R, float) uncompressed scanline OpenEXR; row i = image row i."""
    rows, cols = h.shape

    def attr(name, kind, value):
        return name.encode() + b"\0" + kind.encode() + b"\0" + struct.pack("<i", len(value)) + value

    chlist = b"R\0" + struct.pack("<iB3xii", 2, 0, 1, 1) + b"\0"
    header = (struct.pack("<ii", 20000630, 2)
              + attr("channels", "chlist", chlist)
              + attr("compression", "compression", b"\0")
              + attr("dataWindow", "box2i", struct.pack("<iiii", 0, 0, cols - 1, rows - 1))
              + attr("displayWindow", "box2i", struct.pack("<iiii", 0, 0, cols - 1, rows - 1))
              + attr("lineOrder", "lineOrder", b"\0")
              + attr("pixelAspectRatio", "float", struct.pack("<f", 1.0))
              + attr("screenWindowCenter", "v2f", struct.pack("<ff", 0.0, 0.0))
              + attr("screenWindowWidth", "float", struct.pack("<f", 1.0))
              + b"\0")
    line_bytes = 8 + 4 * cols
    start = len(header) + 8 * rows
    table = b"".join(struct.pack("<Q", start + i * line_bytes) for i in range(rows))
    data = b"".join(struct.pack("<ii", i, 4 * cols) + h[i].astype("<f4").tobytes()
                    for i in range(rows))
    with open(path, "wb") as f:
        f.write(header + table + data)


def check(binary):
    ok = True
    with tempfile.TemporaryDirectory() as tmp:
        for case, c in CASES.items():
            hnp = make_heights(c["size"])
            exr = os.path.join(tmp, f"{case}.exr")
            out = os.path.join(tmp, f"{case}.npy")
            write_exr(exr, hnp)
            x = 0.5 * c["size"] * TEXEL_UM
            subprocess.run([binary, "render", "--heightfield", exr, "--texel-um", str(TEXEL_UM),
                            "--sigma-p-um", str(c["sigma_p_um"]), "--lambda-um", str(LAMBDA_UM),
                            "--resolution", str(c["resolution"]), "--x-um", str(x),
                            "--y-um", str(x), "--out", out, "--precision", "double", "--quiet"],
                           check=True)
            ours = np.load(out)[:, :, 0]
            geo = geometry(c["size"], c["sigma_p_um"], c["resolution"], x, x)
            peak = np.abs(ours).max()
            for dtype in (torch.float64, torch.float32):
                g = to_torch(geo, dtype)
                with torch.no_grad():
                    f = full_slice(slice_values(torch.as_tensor(hnp, dtype=dtype), g), g)
                diff = np.abs(f.double().numpy() - ours)
                line = f"check {case:6s} {str(dtype):14s} max|torch − wavebrdf| / peak = {diff.max() / peak:.2e}"
                if dtype == torch.float64:
                    # The CLI renders in double but stores the slice as float before writing the
                    # .npy, so each value carries float32 rounding (≤ 2⁻²⁴ relative): allow that
                    # plus 1e-10 of the peak. The library itself agrees to ~1e-15 (results file).
                    good = bool(np.all(diff <= 2.0 ** -24 * np.abs(ours) + 1e-10 * peak))
                    ok &= good
                    line += f"; within float32 rounding of the CLI's output + 1e-10·peak: {'ok' if good else 'FAIL'}"
                print(line)
    return ok


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cases", default="thesis,256")
    ap.add_argument("--precisions", default="float32,float64")
    ap.add_argument("--chunks", default="none,1024,128",
                    help="comma-separated pixels per chunk; none = all pixels at once")
    ap.add_argument("--check", action="store_true", help="compare slices with wavebrdf render")
    ap.add_argument("--wavebrdf", default=os.path.join(ROOT, "build", "bin", "wavebrdf"))
    ap.add_argument("--worker", nargs=3, metavar=("CASE", "PRECISION", "CHUNK"),
                    help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        case, precision, chunk = args.worker
        worker(case, precision, None if chunk == "none" else int(chunk))
        return 0
    if args.check and not check(args.wavebrdf):
        return 1
    print(f"torch {torch.__version__}, 2 threads, λ = {LAMBDA_UM} µm, OHS")
    print("| case | precision | chunk (pixels) | kernels × pixels | torch fwd+bwd (median) "
          "| tape | peak RSS Δ |")
    print("|---|---|---|---|---|---|---|")
    for case in args.cases.split(","):
        c = CASES[case]
        pixels = len(geometry(c["size"], c["sigma_p_um"], c["resolution"], 0.0, 0.0)["pix"])
        for chunk in args.chunks.split(","):
            if chunk != "none" and int(chunk) >= pixels:
                continue
            for precision in args.precisions.split(","):
                cmd = [sys.executable, os.path.abspath(__file__), "--worker", case, precision,
                       chunk]
                r = json.loads(subprocess.run(cmd, check=True, capture_output=True,
                                              text=True).stdout.strip().splitlines()[-1])
                print(f"| {case} | {precision} | {chunk} | {r['kernels']} × {r['pixels']} | "
                      f"{fmt_time(r['median_s'])} ({r['runs']} runs) | "
                      f"{fmt_bytes(r['tape_bytes'])} | {fmt_bytes(r['peak_rss_bytes'])} |",
                      flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
