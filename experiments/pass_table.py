#!/usr/bin/env python3
"""Round 11 (docs/recovery.md, "Self-calibration: positions"): the per-pass row of the outer loop
from a recover_study log (outer_passes=N, stdout and /usr/bin/time -v's stderr together).
Usage: pass_table.py LOG [LOG ...]. Per log: the offsets left before each registration (the
outer loop's PROBE, texels) and the final ones (POSITIONS calibrated_rms... against the truth:
error_rms), height_rel_rmse after each recovery's stage 3 (%) and the final one (RESULT), the
registration's moves (rms, texels, after the Newton step and the gauge), the Newton step's
positions moved, the rescue's positions searched, user CPU and peak RSS."""
import re
import sys

for path in sys.argv[1:]:
    lines = open(path).read().splitlines()
    left, pct, moves, newton, rescue = [], [], [], [], []
    last_probe = None
    final_left = final_pct = cpu = rss = None
    in_pass = False
    for line in lines:
        m = re.match(r"PROBE round \d+ offsets_left_rms_texels=([\d.]+)", line)
        if m:
            last_probe = float(m.group(1))
            in_pass = False
            continue
        m = re.match(r"positions:(\w+)\s+(-?\d+) loss (\S+)\s+\S+ s\s+rel_rmse (\S+)", line)
        if m:
            kind, it, loss, rel = m.group(1), int(m.group(2)), float(m.group(3)), float(m.group(4))
            if not in_pass and kind in ("newton", "register"):
                left.append(last_probe)
                pct.append(100 * rel)
                in_pass = True
            if kind == "register":
                moves.append(loss)
            elif kind == "newton":
                newton.append(it)
            elif kind == "rescue":
                rescue.append(f"{it}" + (f" ({loss:.3f})" if loss > 0 else ""))
            continue
        m = re.match(r"POSITIONS error_rms_texels=\S+ calibrated_rms_texels=([\d.]+)", line)
        if m:
            final_left = float(m.group(1))
        m = re.match(r"RESULT .* rel_rmse=([\d.]+)", line)
        if m:
            final_pct = 100 * float(m.group(1))
        m = re.search(r"User time \(seconds\): ([\d.]+)", line)
        if m:
            cpu = float(m.group(1))
        m = re.search(r"Maximum resident set size \(kbytes\): (\d+)", line)
        if m:
            rss = int(m.group(1)) / 1024
    print(path)
    print("  offsets left:", ", ".join(f"{v:.3f}" for v in left), "| final", final_left)
    print("  % per recovery:", ", ".join(f"{v:.3f}" for v in pct), "| final", f"{final_pct:.3f}" if final_pct else None)
    print("  registration moves:", ", ".join(f"{v:.3f}" for v in moves))
    print("  Newton moved:", ", ".join(str(v) for v in newton))
    print("  rescue:", ", ".join(rescue))
    print(f"  user CPU {cpu} s, peak RSS {rss:.0f} MB" if cpu and rss else "  (running)")
