#!/usr/bin/env python3
"""Prints the slowest tests of the last ctest run in a build folder, with their wall times.

Usage: python3 scripts/slowest_tests.py BUILD_DIR [COUNT]   (COUNT default 10)
Reads BUILD_DIR/Testing/Temporary/LastTest.log, which ctest writes on every run: each test's
"N/M Testing: NAME" line is followed by its "Test time = T sec" line.
"""
import os
import re
import sys


def slowest(log_text, count):
    times = []
    name = None
    for line in log_text.splitlines():
        m = re.match(r"^\d+/\d+ Testing: (\S+)", line)
        if m:
            name = m.group(1)
            continue
        m = re.match(r"^Test time =\s*([0-9.]+) sec", line)
        if m and name is not None:
            times.append((float(m.group(1)), name))
            name = None
    times.sort(key=lambda t: (-t[0], t[1]))
    return times[:count], len(times), sum(t for t, _ in times)


def main(argv):
    if len(argv) not in (2, 3):
        sys.stderr.write(__doc__)
        return 2
    log = os.path.join(argv[1], "Testing", "Temporary", "LastTest.log")
    count = int(argv[2]) if len(argv) == 3 else 10
    try:
        with open(log, encoding="utf-8", errors="replace") as f:
            top, total, seconds = slowest(f.read(), count)
    except OSError as e:
        sys.stderr.write(f"slowest_tests: cannot read {log}: {e.strerror}\n")
        return 1
    print(f"{argv[1]}: the {len(top)} slowest of {total} tests ({seconds:.0f} s of test time summed)")
    for t, name in top:
        print(f"  {t:8.2f} s  {name}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
