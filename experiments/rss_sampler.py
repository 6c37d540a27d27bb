#!/usr/bin/env python3
"""Sample a process's resident memory once a second beside its log's last line.

Usage: rss_sampler.py LOG -- COMMAND...   (runs COMMAND with stderr and stdout to LOG)
Writes "seconds rss_MB last-log-line" lines to stdout and, at the end, the peak RSS per
log line (the stage that *ended* last: the samples after a stage's summary line belong to
the next stage's work).
"""
import subprocess
import sys
import time


def rss_kb(pid):
    total = 0
    try:
        with open(f"/proc/{pid}/status") as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    total += int(line.split()[1])
    except OSError:
        return None
    return total


def last_line(path):
    try:
        with open(path, "rb") as f:
            lines = [l for l in f.read().decode(errors="replace").splitlines() if l.strip()]
    except OSError:
        return ""
    # The progress bars are not drawn off a terminal; the stage summaries are lines.
    return lines[-1] if lines else ""


def main():
    sep = sys.argv.index("--")
    log = sys.argv[1]
    cmd = sys.argv[sep + 1:]
    with open(log, "w") as out:
        p = subprocess.Popen(cmd, stdout=out, stderr=subprocess.STDOUT)
    t0 = time.time()
    peak = {}
    order = []
    while p.poll() is None:
        kb = rss_kb(p.pid)
        # /usr/bin/time's child: sample the deepest descendant too.
        try:
            with open(f"/proc/{p.pid}/task/{p.pid}/children") as f:
                kids = f.read().split()
            for k in kids:
                v = rss_kb(int(k))
                if v:
                    kb = max(kb or 0, v)
        except OSError:
            pass
        line = last_line(log)
        if kb is not None:
            print(f"{time.time() - t0:8.0f} {kb / 1024:9.1f} {line[:100]}", flush=True)
            key = line.split(":")[0] + ":" + line.split(":")[1] if line.count(":") > 1 else line[:60]
            if key not in peak:
                order.append(key)
            peak[key] = max(peak.get(key, 0), kb)
        time.sleep(1.0)
    print("# peak RSS (MB) while the last log line was:")
    for k in order:
        print(f"# {peak[k] / 1024:9.1f}  after: {k}")
    sys.exit(p.returncode)


if __name__ == "__main__":
    main()
