"""Whole-process timing for bench/speed.sh: two commands in turn, minima and their ratio.

    python3 bench/whole_process.py RUNS LABEL TARGET -- A... -- [B...]

Runs B then A once each untimed (warm-up: page cache, CPU frequency), then RUNS rounds of B, A
(alternating, so that a drift of the machine's speed touches both alike) and prints one Markdown
row: | LABEL | min B | min A | min B / min A | TARGET |. The time is the wall time from the
start of the child to its reaping (time.perf_counter), output discarded. A failing run prints
the command and its last error line on stderr and "failed" in the row.
"""
import subprocess
import sys
import time


def once(cmd):
    start = time.perf_counter()
    done = subprocess.run(cmd, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    seconds = time.perf_counter() - start
    if done.returncode != 0:
        last = done.stderr.decode(errors="replace").strip().splitlines()[-1:] or ["exit %d" % done.returncode]
        sys.stderr.write("whole_process.py: failed: %s (%s)\n" % (" ".join(cmd), last[0]))
        return None
    return seconds


def cell(times):
    if not times:
        return "-"
    if None in times:
        return "failed"
    best = min(times)
    return "%.4f" % best if best < 0.1 else "%.3f" % best


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
        ratio = "%.1f×" % (min(tb) / min(ta))
    print("| %s | %s | %s | %s | %s |" % (label, cell(tb), cell(ta), ratio, target))


if __name__ == "__main__":
    main(sys.argv[1:])
