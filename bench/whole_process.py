"""Whole-process timing for bench/speed.sh: two commands in turn, minima and their ratio.

    python3 bench/whole_process.py RUNS LABEL TARGET -- A... -- [B...]

Runs B then A once each untimed (warm-up: page cache, CPU frequency), then RUNS rounds of B, A
(alternating, so that a drift of the machine's speed touches both alike) and prints one Markdown
row: | LABEL | min B | min A | min B / min A | TARGET |. The time is the wall time from the
start of the child to its reaping (time.perf_counter), output discarded; beside it, the CPU
time (user + system of the child and its threads, from wait4): on a machine shared with other
work the wall time waits for the processor, the CPU time does not. A failing run prints the
command and its last error line on stderr and "failed" in the row.
"""
import os
import subprocess
import sys
import time


def once(cmd):
    """(wall seconds, CPU seconds) of one run of cmd, or None when it fails."""
    start = time.perf_counter()
    child = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    error = child.stderr.read()
    _, status, usage = os.wait4(child.pid, 0)
    seconds = time.perf_counter() - start
    child.returncode = os.waitstatus_to_exitcode(status)
    if child.returncode != 0:
        last = error.decode(errors="replace").strip().splitlines()[-1:] or ["exit %d" % child.returncode]
        sys.stderr.write("whole_process.py: failed: %s (%s)\n" % (" ".join(cmd), last[0]))
        return None
    return seconds, usage.ru_utime + usage.ru_stime


def fmt(t):
    return "%.4f" % t if t < 0.1 else "%.3f" % t


def cell(runs):
    if not runs:
        return "-"
    if None in runs:
        return "failed"
    return "%s (cpu %s)" % (fmt(min(r[0] for r in runs)), fmt(min(r[1] for r in runs)))


def main(argv):
    if len(argv) < 5 or argv[3] != "--" or "--" not in argv[4:]:
        sys.exit("usage: whole_process.py RUNS LABEL TARGET -- A... -- [B...]")
    runs = int(argv[0])
    if runs < 1:
        sys.exit("whole_process.py: RUNS %d; expected at least 1" % runs)
    label, target = argv[1], argv[2]
    rest = argv[4:]
    split = rest.index("--")
    a, b = rest[:split], rest[split + 1:]
    ta, tb = [], []
    if b:
        once(b)
    once(a)
    for _ in range(runs):
        if b:
            tb.append(once(b))
        ta.append(once(a))
    ratio = "-"
    if ta and tb and None not in ta and None not in tb:
        wall = min(r[0] for r in tb) / min(r[0] for r in ta)
        cpu = min(r[1] for r in tb) / max(min(r[1] for r in ta), 1e-6)
        ratio = "%.1f× (cpu %.1f×)" % (wall, cpu)
    print("| %s | %s | %s | %s | %s |" % (label, cell(tb), cell(ta), ratio, target))


if __name__ == "__main__":
    main(sys.argv[1:])
