#!/usr/bin/env bash
# Applies the house style (.clang-format at the repository root) to our C++ sources: include/,
# src/, apps/, python/ (the bindings), tests/, bench/, fuzz/ and experiments/. Only files git
# knows of (tracked, or new and not ignored), so build trees are never touched; the CIE table
# (src/**/*.inc) is data and is left as it is.
# Usage: bash scripts/format.sh           rewrite the files in place
#        bash scripts/format.sh --check   change nothing; fail and list what would change
# Environment: CLANG_FORMAT (the clang-format program, default clang-format).
set -euo pipefail
cd "$(dirname "$0")/.."

clang_format="${CLANG_FORMAT:-clang-format}"
mode=(-i)
case "${1:-}" in
    "") ;;
    --check) mode=(--dry-run -Werror) ;;
    *) echo "usage: bash scripts/format.sh [--check]" >&2; exit 2 ;;
esac
if ! command -v "$clang_format" >/dev/null 2>&1; then
    echo "format: $clang_format not found (Debian: apt-get install clang-format, or set CLANG_FORMAT)" >&2
    exit 1
fi

files=()
while IFS= read -r -d '' f; do
    [ -f "$f" ] && files+=("$f")
done < <(git ls-files -z --cached --others --exclude-standard -- \
    'include/*.h' 'src/*.h' 'src/*.cpp' 'apps/*.h' 'apps/*.cpp' 'python/*.h' 'python/*.cpp' \
    'tests/*.h' 'tests/*.cpp' 'bench/*.h' 'bench/*.cpp' 'fuzz/*.h' 'fuzz/*.cpp' \
    'experiments/*.h' 'experiments/*.cpp' | sort -zu)
[ ${#files[@]} -gt 0 ] || { echo "format: no C++ sources found" >&2; exit 1; }

echo "format: ${#files[@]} files with $("$clang_format" --version | head -n 1)"
"$clang_format" --style=file "${mode[@]}" -- "${files[@]}"
