#!/usr/bin/env python3
"""Checks that no function in src/ is longer than LIMIT lines (default 200).

A long function holds many locals that every part of it may touch, so nobody can change one
part safely; split it into named pieces with clear inputs and outputs (a struct or a small class
where many locals are shared). The scan is a brace matcher over src/**/*.cpp and src/**/*.h with
comments, string and character literals (raw strings included) and preprocessor lines blanked
out: a brace at namespace or class scope whose head (the text since the previous ';', '{' or
'}') holds a parenthesis opens a function body, and the function's length runs from the head's
first line to the closing brace's line. Lambdas and local classes count towards the function
that holds them.
Usage: python3 scripts/check_function_length.py [--limit N] [ROOT]
(exit 1 and one line per function over the limit: path:line name length)
"""
import argparse
import os
import re
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
LIMIT = 200


def blank(text):
    """The text with comments, literals and preprocessor lines replaced by spaces (newlines kept)."""
    out = []
    i, n = 0, len(text)
    line_start = True
    while i < n:
        c = text[i]
        if line_start and c in " \t":
            out.append(c)
            i += 1
            continue
        if line_start and c == "#":  # a preprocessor line, with its continuations
            while i < n and text[i] != "\n":
                if text[i] == "\\" and i + 1 < n and text[i + 1] == "\n":
                    out.append(" \n")
                    i += 2
                    continue
                out.append(" ")
                i += 1
            continue
        line_start = c == "\n"
        if text.startswith("//", i):
            j = text.find("\n", i)
            j = n if j < 0 else j
            out.append(" " * (j - i))
            i = j
        elif text.startswith("/*", i):
            j = text.find("*/", i + 2)
            j = n if j < 0 else j + 2
            out.append(re.sub(r"[^\n]", " ", text[i:j]))
            i = j
        elif c == '"' or c == "'":
            prefix = re.search(r"(?:u8|u|U|L)?R$", text[max(0, i - 3):i])
            if c == '"' and prefix and not re.match(r"[\w]", text[i - len(prefix.group(0)) - 1:i - len(prefix.group(0))] or " "):
                m = re.match(r'"([^(\s]{0,16})\(', text[i:])
                if m:  # a raw string: R"delim( ... )delim"
                    end = text.find(")" + m.group(1) + '"', i)
                    j = n if end < 0 else end + len(m.group(1)) + 2
                    out.append(re.sub(r"[^\n]", " ", text[i:j]))
                    i = j
                    continue
            if c == "'" and i > 0 and re.match(r"[0-9A-Fa-f]", text[i - 1]) and i + 1 < n and re.match(r"[0-9A-Fa-f]", text[i + 1]):
                out.append(" ")  # a digit separator (1'000'000)
                i += 1
                continue
            j = i + 1
            while j < n and text[j] != c and text[j] != "\n":
                j += 2 if text[j] == "\\" else 1
            j = min(j + 1, n)
            out.append(re.sub(r"[^\n]", " ", text[i:j]))
            i = j
        else:
            out.append(c)
            i += 1
    return "".join(out)


SCOPE_RE = re.compile(r"^(?:inline\s+)?namespace\b|^extern\s*$")
CLASS_RE = re.compile(r"\b(?:class|struct|union)\b")
ENUM_RE = re.compile(r"\benum\b")
ACCESS_RE = re.compile(r"^(?:\s*\b(?:public|private|protected)\s*:(?!:))+")
NAME_RE = re.compile(r"((?:[A-Za-z_~][\w]*\s*::\s*)*(?:operator\s*[^\s(]+|operator\s*\(\s*\)|[A-Za-z_~][\w]*))\s*(?:<[^()]*>)?\s*\(")


def functions(text):
    """(first line, last line, name) of every function body at namespace or class scope."""
    code = blank(text)
    found = []
    stack = []  # per open brace: "scope" (namespace, extern, class) or "body" / "other"
    head_start = 0
    line = 1
    for i, c in enumerate(code):
        if c == "\n":
            line += 1
            continue
        if c not in "{};":
            continue
        at_scope = all(kind == "scope" for kind, _, _ in stack)
        if c == "{":
            # The head without the access specifiers before it (public:, private:, protected:).
            raw = ACCESS_RE.sub("", code[head_start:i]).lstrip()
            head = raw.strip()
            if not at_scope:
                kind = "other"
            elif SCOPE_RE.search(head) or (CLASS_RE.search(head) and "(" not in head) or head == "":
                kind = "scope"
            elif ENUM_RE.search(head) or "(" not in head:
                kind = "other"
            else:
                kind = "body"
            first = line - raw.count("\n") if kind == "body" else line
            stack.append((kind, first, head))
            head_start = i + 1
        elif c == "}":
            if stack:
                kind, first, head = stack.pop()
                if kind == "body":
                    m = NAME_RE.search(head)
                    name = re.sub(r"\s+", "", m.group(1)) if m else head.splitlines()[0][:40]
                    found.append((first, line, name))
            head_start = i + 1
        else:  # ';' ends a declaration at scope level; inside a body it changes nothing
            if all(kind == "scope" for kind, _, _ in stack):
                head_start = i + 1
    return found


def long_functions(root, limit):
    """(path, first line, name, lines) of every function over `limit` lines under root/src."""
    over = []
    src = os.path.join(root, "src")
    for d, _, names in sorted(os.walk(src)):
        for name in sorted(names):
            if not name.endswith((".cpp", ".h")):
                continue
            path = os.path.join(d, name)
            with open(path, encoding="utf-8") as f:
                text = f.read()
            for first, last, fn in functions(text):
                if last - first + 1 > limit:
                    over.append((os.path.relpath(path, root), first, fn, last - first + 1))
    return over


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--limit", type=int, default=LIMIT, help="most lines a function may have (default 200)")
    parser.add_argument("root", nargs="?", default=ROOT, help="the repository (its src/ is scanned)")
    args = parser.parse_args()
    if args.limit < 1:
        parser.error(f"--limit {args.limit} is invalid; expected 1 or more")
    if not os.path.isdir(os.path.join(args.root, "src")):
        parser.error(f"{args.root} has no src/ folder; expected the repository's root")
    over = long_functions(args.root, args.limit)
    for path, first, fn, lines in over:
        print(f"{path}:{first}: {fn} is {lines} lines; expected at most {args.limit} (split it into named pieces)")
    return 1 if over else 0


if __name__ == "__main__":
    sys.exit(main())
