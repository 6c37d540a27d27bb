"""Clear messages for calls that do not match a function's parameters.

pybind11 answers a call with a missing or misspelt keyword by "incompatible function
arguments" and every overload's whole signature. explained(f) calls f and, on that error only,
names what is wrong from the signature line of f's docstring: the required parameter that is
missing, a keyword that f does not have (with the nearest one it has), or too many positional
arguments. Any other TypeError (a value of the wrong type) is pybind11's, unchanged.
It also passes every os.PathLike argument (a pathlib.Path) as its str (os.fspath), so that each
wrapped function takes paths as str or Path alike.
"""
from __future__ import annotations

import functools
import os  # already loaded by the interpreter: costs nothing

# difflib, re and typing are imported where used (a misspelt call, a type checker): together
# they were half of `import wavebrdf`'s own time.
TYPE_CHECKING = False
if TYPE_CHECKING:
    from typing import Callable, List, Optional, Tuple, TypeVar

    F = TypeVar("F", bound=Callable)


def _split(text: str) -> List[str]:
    """The parameters of a signature's argument list, split at top-level commas."""
    parts, depth, current = [], 0, ""
    for ch in text:
        if ch in "([{":
            depth += 1
        elif ch in ")]}":
            depth -= 1
        elif ch == "," and depth == 0:
            parts.append(current.strip())
            current = ""
            continue
        current += ch
    if current.strip():
        parts.append(current.strip())
    return parts


def parameters(name: str, doc: Optional[str]) -> Optional[List[Tuple[str, bool, bool]]]:
    """(name, required, keyword_only) of each parameter of the first signature line
    "NAME(a: T, *, b: T = ...) -> R" of `doc`, or None when there is none (or several overloads)."""
    if not doc:
        return None
    first = doc.lstrip().splitlines()[0] if doc.strip() else ""
    if not first.startswith(name + "(") or "Overloaded function" in doc[:200]:
        return None
    depth, end = 0, None
    for k, ch in enumerate(first[len(name):], len(name)):
        depth += ch in "([{"
        depth -= ch in ")]}"
        if depth == 0:
            end = k
            break
    if end is None:
        return None
    import re

    out, keyword_only = [], False
    for part in _split(first[len(name) + 1:end]):
        if part == "*":
            keyword_only = True
            continue
        if part.startswith("*"):
            return None  # *args / **kwargs: anything goes
        match = re.match(r"([A-Za-z_][A-Za-z_0-9]*)", part)
        if not match:
            return None
        out.append((match.group(1), "=" not in part, keyword_only))
    return out


def diagnose(name: str, doc: Optional[str], args: tuple, kwargs: dict) -> Optional[str]:
    """What is wrong with calling NAME(*args, **kwargs), or None when it cannot tell."""
    params = parameters(name, doc)
    if params is None:
        return None
    names = [p[0] for p in params]
    for key in kwargs:
        if key not in names:
            import difflib

            near = difflib.get_close_matches(key, names, n=1, cutoff=0.6)
            hint = f"; did you mean {near[0]!r}?" if near else "; expected one of " + ", ".join(names)
            return f"{name}() got an unexpected keyword argument {key!r}{hint}"
    positional = [p for p in params if not p[2]]
    if len(args) > len(positional):
        return (f"{name}() takes {len(positional)} positional argument(s) but {len(args)} were given; "
                "the others are keywords: " + ", ".join(p[0] + "=" for p in params if p[2]))
    given = set(names[: len(args)]) | set(kwargs)
    for param, required, keyword_only in params:
        if param in given and param in kwargs and names.index(param) < len(args):
            return f"{name}() got multiple values for argument {param!r}"
    missing = [p for p in params if p[1] and p[0] not in given]
    if missing:
        param, _, keyword_only = missing[0]
        kind = "keyword argument" if keyword_only else "argument"
        return f"{name}() missing required {kind} {param!r} ({param}=...)"
    return None


def explained(function: F) -> F:
    """`function` with the clearer messages above for calls that do not match its parameters,
    and path-like arguments passed as str."""
    name = getattr(function, "__name__", "")

    @functools.wraps(function)
    def call(*args, **kwargs):
        args = tuple(os.fspath(a) if isinstance(a, os.PathLike) else a for a in args)
        kwargs = {k: os.fspath(v) if isinstance(v, os.PathLike) else v for k, v in kwargs.items()}
        try:
            return function(*args, **kwargs)
        except TypeError as error:
            if "incompatible function arguments" not in str(error):
                raise
            message = diagnose(name, getattr(function, "__doc__", None), args, kwargs)
            if message is None:
                raise
            raise TypeError(message) from None

    return call  # type: ignore[return-value]
