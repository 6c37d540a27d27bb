#!/usr/bin/env python3
"""Issue 14's validation: every instrument error the recovery must handle, on seeds never used
while developing (9001–9003 by default), through `wavebrdf recover` (the CLI) and through
`wavebrdf.recover` (Python), one line per run in out/instrument/summary.csv and a Markdown table
(experiments/instrument.md is the committed copy of a run).

    PYTHONPATH=build/python /usr/bin/python3 experiments/instrument.py [--seeds 9001,9002,9003]
        [--cases all|name,name] [--interfaces cli,python] [--out out/instrument]

Every case is the issue's setting: 32² (or as stated), ±1 µm, correlation 4 texels, planner
defaults at 48² slices, recovered with the nominal metadata plus self-calibration where the
case calls for it. A run prints its line as it ends, so a long study shows its progress.
"""
import argparse
import csv
import json
import os
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# name: (CLI arguments, Python keyword arguments, target height_rel_rmse in percent or None)
CASES = {
    "exact": (["--size", "32", "--resolution", "48"], dict(size=32, resolution=48), 0.05),
    "positions_1": (["--size", "32", "--resolution", "48", "--calibrate", "positions",
                     "--simulate-position-error-texels", "1"],
                    dict(size=32, resolution=48, calibrate="positions", simulate_position_error_texels=1.0),
                    0.1),
    "positions_3": (["--size", "32", "--resolution", "48", "--calibrate", "positions",
                     "--simulate-position-error-texels", "3"],
                    dict(size=32, resolution=48, calibrate="positions", simulate_position_error_texels=3.0),
                    1.0),
    "exposure": (["--size", "32", "--resolution", "48", "--calibrate", "exposure", "--simulate-exposure", "0.5,2"],
                 dict(size=32, resolution=48, calibrate="exposure", simulate_exposure=(0.5, 2.0)), 0.1),
    "sigma_1.3": (["--size", "32", "--resolution", "48", "--calibrate", "sigma", "--simulate-sigma-factor", "1.3"],
                  dict(size=32, resolution=48, calibrate="sigma", simulate_sigma_factor=1.3), 0.1),
    "all_at_once": (["--size", "32", "--resolution", "48", "--calibrate", "all", "--noise", "poisson:1e4",
                     "--simulate-position-error-texels", "1", "--simulate-exposure", "0.5,2",
                     "--simulate-sigma-factor", "1.3"],
                    dict(size=32, resolution=48, calibrate="all", noise="poisson:1e4",
                         simulate_position_error_texels=1.0, simulate_exposure=(0.5, 2.0),
                         simulate_sigma_factor=1.3), 0.5),
    "white_32": (["--size", "32", "--resolution", "48", "--spectral", "8"],
                 dict(size=32, resolution=48, spectral=8), 1.0),
    "white_64": (["--size", "64", "--resolution", "48", "--spectral", "8"],
                 dict(size=64, resolution=48, spectral=8), 1.0),
    "scalar_calibrated": (["--size", "32", "--resolution", "48", "--simulator", "scalar", "--calibrate",
                           "exposure,sigma"],
                          dict(size=32, resolution=48, simulator="scalar", calibrate="exposure,sigma"), 0.2),
    "rough_4um": (["--size", "32", "--resolution", "48", "--height-range-um", "8"],
                  dict(size=32, resolution=48, height_range_um=8.0), 1.0),
    "correlation_2": (["--size", "32", "--resolution", "48", "--correlation-texels", "2"],
                      dict(size=32, resolution=48, correlation_texels=2.0), 1.0),
    "oblique_ghs": (["--size", "32", "--resolution", "48", "--model", "GHS", "--light-x", "0.3"],
                    dict(size=32, resolution=48, model="GHS", light=(0.3, 0.0)), None),
    "uncertainty": (["--size", "32", "--resolution", "48", "--noise", "poisson:1e4", "--uncertainty"],
                    dict(size=32, resolution=48, noise="poisson:1e4", uncertainty=True), None),
}


def last_metrics_cli(run_dir):
    with open(os.path.join(run_dir, "metrics.csv")) as f:
        rows = list(csv.reader(f))
    header, last = rows[0], rows[-1]
    values = dict(zip(header, last))
    return float(values["height_rel_rmse"]), float(values["height_rel_rmse_plane_removed"])


def run_cli(binary, name, seed, args, out):
    run_dir = os.path.join(out, f"{name}_{seed}_cli")
    argv = [binary, "recover", *args, "--seed", str(seed), "--out", run_dir, "--force", "--quiet", "--no-plots"]
    start = time.monotonic()
    subprocess.run(argv, check=True)
    seconds = time.monotonic() - start
    err, err_plane = last_metrics_cli(run_dir)
    coverage = ""
    path = os.path.join(run_dir, "uncertainty.json")
    if os.path.exists(path):
        coverage = json.load(open(path)).get("coverage_2sigma", "")
    return err, err_plane, seconds, coverage


def run_python(wb, name, seed, kwargs):
    start = time.monotonic()
    # The rarely used options go in a RecoverSettings (recover()'s settings=).
    rare = {k: v for k, v in kwargs.items() if hasattr(wb.RecoverSettings, k)}
    common = {k: v for k, v in kwargs.items() if k not in rare}
    result = wb.recover(seed=seed, quiet=True, settings=wb.RecoverSettings(**rare), **common)
    seconds = time.monotonic() - start
    m = result.metrics
    err = float(m["height_rel_rmse"][-1])
    err_plane = float(m["height_rel_rmse_plane_removed"][-1])
    return err, err_plane, seconds, ""


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", default="9001,9002,9003")
    parser.add_argument("--cases", default="all")
    parser.add_argument("--interfaces", default="cli,python")
    parser.add_argument("--out", default=os.path.join(ROOT, "out", "instrument"))
    parser.add_argument("--binary", default=os.path.join(ROOT, "build", "bin", "wavebrdf"))
    a = parser.parse_args()
    seeds = [int(s) for s in a.seeds.split(",")]
    names = list(CASES) if a.cases == "all" else a.cases.split(",")
    for n in names:
        if n not in CASES:
            sys.exit(f"instrument.py: unknown case '{n}' (expected one of {', '.join(CASES)})")
    interfaces = a.interfaces.split(",")
    os.makedirs(a.out, exist_ok=True)
    wb = None
    if "python" in interfaces:
        import wavebrdf as wb
    summary = os.path.join(a.out, "summary.csv")
    new = not os.path.exists(summary)
    with open(summary, "a", newline="") as f:
        w = csv.writer(f)
        if new:
            w.writerow(["case", "interface", "seed", "height_rel_rmse_pct", "plane_removed_pct", "target_pct",
                        "met", "seconds", "coverage_2sigma"])
        for n in names:
            args, kwargs, target = CASES[n]
            for seed in seeds:
                for interface in interfaces:
                    if interface == "cli":
                        err, err_plane, secs, cov = run_cli(a.binary, n, seed, args, a.out)
                    else:
                        err, err_plane, secs, cov = run_python(wb, n, seed, kwargs)
                    pct, pct_plane = 100 * err, 100 * err_plane
                    met = "" if target is None else ("yes" if pct <= target else "NO")
                    row = [n, interface, seed, f"{pct:.4f}", f"{pct_plane:.4f}", target if target else "",
                           met, f"{secs:.1f}", cov]
                    w.writerow(row)
                    f.flush()
                    print(",".join(str(x) for x in row), flush=True)


if __name__ == "__main__":
    main()
