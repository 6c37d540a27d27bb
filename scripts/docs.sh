#!/usr/bin/env bash
# Builds the API reference (CI runs it from scripts/test.sh):
#  - C++: Doxygen over include/wavebrdf (the headers' comments, through docs/doxygen_filter.py)
#    with README.md as the main page and docs/*.md as pages → build/docs/html/index.html;
#  - Python: pydoc of the built module's docstrings → build/docs/python/wavebrdf*.html (the
#    same text as help(wb.x)); skipped with a note when the module is not built.
# Fails on any Doxygen warning (a broken comment command, a link to a file that does not exist,
# ...) except two kinds, which it reports: members without a comment (counted, listed in
# build/docs/undocumented.txt) and Markdown links to repository files that exist but are not
# Doxygen pages (GitHub resolves them). Usage: bash scripts/docs.sh  (about 10 s)
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$(pwd)
BUILD=${WAVEBRDF_BUILD_DIR:-build}
command -v doxygen >/dev/null || { echo "docs: doxygen is missing (bash scripts/setup.sh installs it)" >&2; exit 1; }
rm -rf build/docs
mkdir -p build/docs
WAVEBRDF_VERSION=$(cat VERSION) doxygen docs/Doxyfile
/usr/bin/python3 - "$ROOT" build/docs/warnings.log <<'PY'
import os, re, sys
root, log = sys.argv[1], sys.argv[2]
fatal, undocumented = [], []
for line in open(log, encoding="utf-8", errors="replace").read().splitlines():
    if not line.strip():
        continue
    if "is not documented" in line:
        undocumented.append(line.replace(root + "/", ""))
        continue
    link = re.search(r"^(.*?):\d+: warning: unable to resolve reference to '([^']+)' for \\ref command", line)
    if link:
        target = link.group(2)
        where = os.path.dirname(link.group(1))
        if any(os.path.isfile(p) for p in (target, os.path.join(where, target), os.path.join(root, target))):
            continue
    fatal.append(line.replace(root + "/", ""))
with open(os.path.join(os.path.dirname(log), "undocumented.txt"), "w", encoding="utf-8") as out:
    out.write("\n".join(undocumented) + "\n")
print("docs: C++ reference in build/docs/html/index.html; %d members without a comment "
      "(build/docs/undocumented.txt)" % len(undocumented))
if fatal:
    print("docs: %d Doxygen warning(s):" % len(fatal), *fatal, sep="\n  ", file=sys.stderr)
    sys.exit(1)
PY
if [ -d "$BUILD/python/wavebrdf" ]; then
    mkdir -p build/docs/python
    (cd build/docs/python &&
        PYTHONPATH="$ROOT/$BUILD/python" /usr/bin/python3 -m pydoc -w wavebrdf wavebrdf._core wavebrdf.torch \
            wavebrdf.report >/dev/null)
    for page in wavebrdf wavebrdf._core wavebrdf.torch wavebrdf.report; do
        [ -s "build/docs/python/$page.html" ] || { echo "docs: pydoc wrote no $page.html" >&2; exit 1; }
    done
    echo "docs: Python reference in build/docs/python/wavebrdf.html"
else
    echo "docs: $BUILD/python/wavebrdf is not built; no Python reference (help(wb.x) has the same text)"
fi
