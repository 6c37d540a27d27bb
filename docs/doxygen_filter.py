#!/usr/bin/env python3
"""Doxygen input filter for include/wavebrdf. The headers document every declaration with plain
`//` comments (the house style: a short block above each public function); this turns them into
Doxygen comments on the fly, so the headers stay as they are:
- a comment line becomes `///`; a comment after a declaration `///<` (a member's description);
- the comment block at the top of a file becomes the file's description (`#pragma once`, the
  line above it, becomes `/// \\file`, so line numbers stay those of the header);
- backslashes in comments are escaped (`'\\r'` is text, not a Doxygen command)."""
import re
import sys

COMMENT = re.compile(r"^(\s*)//(?!/)\s?(.*)$")
CODE_THEN_COMMENT = re.compile(r"^(\s*[^\s/\"'][^\"']*?;)(\s*)//(?!/)\s?(.*)$")


def text(comment):
    return re.sub(r"\\", r"\\\\", comment)


def main(path):
    lines = open(path, encoding="utf-8").read().split("\n")
    out = []
    i = 0
    while i < len(lines):
        line = lines[i]
        if line.startswith("#pragma once"):  # replaced: the file's description starts here
            out.append("/// \\file")
            i += 1
            continue
        comment = COMMENT.match(line)
        if comment:
            j = i
            while j < len(lines) and COMMENT.match(lines[j]):
                j += 1
            block = [COMMENT.match(lines[k]) for k in range(i, j)]
            out += [m.group(1) + "/// " + text(m.group(2)) for m in block]
            i = j
            continue
        trailing = CODE_THEN_COMMENT.match(line)
        out.append(trailing.group(1) + trailing.group(2) + "///< " + text(trailing.group(3)) if trailing else line)
        i += 1
    sys.stdout.write("\n".join(out))


if __name__ == "__main__":
    main(sys.argv[1])
