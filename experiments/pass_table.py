#!/usr/bin/env python3
"""Round 11 (experiments/2026-11-23-position-calibration.md): the per-pass row of the outer loop
from a recover_study log (outer_passes=N, stdout and /usr/bin/time -v's stderr together).
Usage: pass_table.py LOG [LOG ...]. Per log: the offsets left before each registration (the
outer loop's PROBE, texels) and the final ones (POSITIONS calibrated_rms... against the truth:
error_rms), height_rel_rmse after each recovery's stage 3 (%) and the final one (RESULT), the
registration's moves (rms, texels, after the Newton step and the gauge), the Newton step's
positions moved, the rescue's positions searched, user CPU and peak RSS.
Round 12b: stage 3's final loss per recovery (the last "refine" line of each, printed every 10
iterations: exact when stage 3 ends on a multiple of 10), which passes ran the field stage, and
with --stall N,TOL[;N,TOL...] where the loop's stall rule (PositionLoopSettings' stall_passes N,
stall_tolerance TOL; recover_study stall_passes=N stall_tolerance=TOL) would have stopped a log of the loop run without it (the
passes before the stop are the same bits), with the % after that pass's stage 3."""
import re
import sys

rules = []
args = sys.argv[1:]
if args and args[0] == "--stall":
    rules = [(int(r.split(",")[0]), float(r.split(",")[1])) for r in args[1].split(";")]
    args = args[2:]


def stall_stop(losses, field, passes, tolerance):
    """The pass (1-based) after which the stall rule stops, or None (recover.cpp, round 12b)."""
    best, stalled = losses[0], 0
    for k in range(1, len(losses)):
        if field[k]:
            stalled = 0
        else:
            stalled = stalled + 1 if losses[k] > (1.0 - tolerance) * best else 0
            if stalled >= passes:
                return k
        best = min(best, losses[k])
    return None


for path in args:
    lines = open(path).read().splitlines()
    left, pct, moves, newton, rescue = [], [], [], [], []
    refine_loss, refine_pct, field = [], [], [False]
    last_refine = None
    last_probe = None
    final_left = final_pct = cpu = rss = None
    in_pass = False
    for line in lines:
        m = re.match(r"refine\s+(\d+) loss (\S+)\s+\S+ s\s+rel_rmse (\S+)", line)
        if m:
            last_refine = (int(m.group(1)), float(m.group(2)), 100 * float(m.group(3)))
        m = re.match(r"unwrap\s+(\d+) ", line)
        if m and int(m.group(1)) >= 1 and len(field) == len(refine_loss) + 1 and len(refine_loss) > 0:
            field[-1] = True
        if re.match(r"(positions:newton|positions:register|misfit:gabor|RESULT)", line) and last_refine:
            refine_loss.append(last_refine[1])
            refine_pct.append(last_refine[2])
            last_refine = None
            if line.startswith("positions"):
                field.append(False)
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
    print("  stage 3 final loss:", ", ".join(f"{v:.4e}" for v in refine_loss))
    print("  field stage in pass:", "".join("F" if f else "-" for f in field[1:len(refine_loss)]))
    for n, tol in rules:
        k = stall_stop(refine_loss, field[:len(refine_loss)], n, tol)
        where = f"after pass {k}: {refine_pct[k]:.3f} %" if k is not None else f"not ({len(refine_loss) - 1} passes)"
        print(f"  stall rule N={n} tol={tol}: stops {where}")
