#!/usr/bin/env python3
"""Checks that src/ includes only run down the stages of docs/architecture.md.

The order is core -> surface -> forward -> adjoint -> inverse -> recovery; io needs core, surface
and forward (a table file stores forward's results); image and design sit beside inverse (forward,
adjoint, io); the plugins' C tables count as core. A public header include/wavebrdf/X.h belongs to
the stage whose folder holds X.cpp (or X_*.cpp); an internal header "stage/x.h" to its folder; a header-only public header without a
source to core. Every include of a later stage (or of a stage beside it: image <-> design) is an
error, except those listed in KNOWN, the arrows still to be removed; a KNOWN entry that no longer
occurs is an error too, so the list only shrinks.
Usage: python3 scripts/check_layers.py  (exit 1 and one line per arrow when one runs back)
"""
import os
import re
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
ALLOWED = {
    "core": {"core"},
    "surface": {"core", "surface"},
    "io": {"core", "surface", "forward", "io"},
    "forward": {"core", "surface", "forward"},
    "adjoint": {"core", "surface", "forward", "adjoint"},
    "inverse": {"core", "surface", "io", "forward", "adjoint", "inverse"},
    "recovery": {"core", "surface", "io", "forward", "adjoint", "inverse", "recovery"},
    "image": {"core", "surface", "io", "forward", "adjoint", "image"},
    "design": {"core", "surface", "io", "forward", "adjoint", "inverse", "design"},
    # Loaded at run time through the C tables of plugins/*_api.h, which count as core.
    "plugins": {"core", "surface", "io", "forward", "adjoint", "inverse", "plugins"},
}
# (file, included header): arrows that run back up today; remove an entry with its arrow.
KNOWN = set()


def stage_of_public(header, sources):
    stem = header[: -len(".h")]
    for stage, names in sources.items():
        if any(os.path.basename(n) == stem + ".cpp" or os.path.basename(n).startswith(stem + "_") for n in names):
            return stage
    return "core"


def main():
    src = os.path.join(ROOT, "src")
    sources = {}
    for s in ALLOWED:
        if os.path.isdir(os.path.join(src, s)):
            sources[s] = [os.path.relpath(os.path.join(d, n), os.path.join(src, s))
                          for d, _, names in os.walk(os.path.join(src, s)) for n in names]
    include_re = re.compile(r'^\s*#\s*include\s+"([^"]+)"')
    files = []
    for stage in sources:
        for name in sorted(sources[stage]):
            if name.endswith((".cpp", ".h")):
                files.append((stage, os.path.join("src", stage, name)))
    for name in sorted(os.listdir(os.path.join(ROOT, "include", "wavebrdf"))):
        if name.endswith(".h"):
            files.append((stage_of_public(name, sources), os.path.join("include", "wavebrdf", name)))
    errors, seen = [], set()
    for d in sorted(os.listdir(src)):
        if os.path.isdir(os.path.join(src, d)) and d not in ALLOWED:
            errors.append(f"src/{d}: a folder of no known stage: add it to ALLOWED in scripts/check_layers.py")
    for stage, path in files:
        with open(os.path.join(ROOT, path), encoding="utf-8") as f:
            for number, line in enumerate(f, 1):
                m = include_re.match(line)
                if not m:
                    continue
                target = m.group(1)
                if target.startswith("wavebrdf/"):
                    to = stage_of_public(target[len("wavebrdf/"):], sources)
                elif target.startswith("plugins/") and target.endswith("_api.h"):
                    to = "core"
                elif target.split("/")[0] in ALLOWED:
                    to = target.split("/")[0]
                else:
                    continue  # a sibling file (e.g. a .inc table) or a plugin header
                if to in ALLOWED[stage]:
                    continue
                if (path, target) in KNOWN:
                    seen.add((path, target))
                    continue
                errors.append(f"{path}:{number}: {stage} includes {target} ({to}), a later stage")
    for path, target in sorted(KNOWN - seen):
        errors.append(f"{path}: no longer includes {target}: remove it from KNOWN in scripts/check_layers.py")
    for e in errors:
        print(e, file=sys.stderr)
    return 1 if errors else 0


if __name__ == "__main__":
    sys.exit(main())
