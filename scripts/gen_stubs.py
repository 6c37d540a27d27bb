#!/usr/bin/env python3
"""Writes python/wavebrdf/_core.pyi, the type stubs of the extension wavebrdf._core, from the
signatures and docstrings pybind11 gives every function, method and property (pybind11-stubgen
is not needed). Run it after changing a binding, with the module of a fresh build on the path:

    PYTHONPATH=build/python /usr/bin/python3 scripts/gen_stubs.py [--check] [OUT]

--check writes nothing and exits 1 when OUT (default python/wavebrdf/_core.pyi) differs from
what would be written. tests/python/test_stubs.py checks the stubs against the module
independently (names and parameter names).
"""
import argparse
import importlib
import inspect
import os
import re
import sys

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
DEFAULT_OUT = os.path.join(ROOT, "python", "wavebrdf", "_core.pyi")
MODULE = "wavebrdf._core"
TYPING = ("Any", "Callable", "Dict", "Iterable", "Iterator", "List", "Optional", "Sequence", "Set", "Tuple",
          "Union")
# pybind11's names for what a C++ argument accepts, as stub types.
PLAIN = {"handle": "Any", "object": "Any", "capsule": "Any", "buffer": "Any", "iterable": "Iterable[Any]",
         "iterator": "Iterator[Any]", "function": "Callable[..., Any]", "args": "Any", "kwargs": "Any",
         "numpy.ndarray": "numpy.ndarray", "array": "numpy.ndarray",
         # std::filesystem::path arguments take str or any os.PathLike (pathlib.Path).
         "os.PathLike": "Union[str, os.PathLike]"}


def split_top_level(text, separator=","):
    """`text` split at `separator` outside brackets and quotes."""
    parts, depth, quote, current = [], 0, None, []
    for ch in text:
        if quote:
            current.append(ch)
            if ch == quote:
                quote = None
            continue
        if ch in "'\"":
            quote = ch
        elif ch in "([{<":
            depth += 1
        elif ch in ")]}>":
            depth -= 1
        elif ch == separator and depth == 0:
            parts.append("".join(current).strip())
            current = []
            continue
        current.append(ch)
    if "".join(current).strip():
        parts.append("".join(current).strip())
    return parts


# C++ types pybind11 names by their C++ name (a signature made before the class was bound).
CPP_NAMES = {"wavebrdf::GaborRepresentation": "GaborRep"}


def stub_type(text):
    """A pybind11 type string as a stub annotation."""
    text = text.strip().replace(MODULE + ".", "")
    if "::" in text:
        if text not in CPP_NAMES:
            print("gen_stubs: warning: C++ type %s has no Python name (add it to CPP_NAMES); written as Any" % text,
                  file=sys.stderr)
        return CPP_NAMES.get(text, "Any")
    if text in PLAIN:
        return PLAIN[text]
    # numpy.ndarray[numpy.float64[m, n], flags.writeable] and the like: the array type.
    if text.startswith("numpy.ndarray["):
        return "numpy.ndarray"
    m = re.match(r"^([\w.]+)\[(.*)\]$", text)
    if m:
        inner = [stub_type(t) for t in split_top_level(m.group(2))]
        if m.group(1) == "Callable" and inner and not inner[0].startswith("["):
            inner = ["[" + inner[0] + "]"] + inner[1:]
        return "%s[%s]" % (m.group(1), ", ".join(inner))
    if text.startswith("[") and text.endswith("]"):  # a Callable's argument list
        return "[" + ", ".join(stub_type(t) for t in split_top_level(text[1:-1])) + "]"
    return PLAIN.get(text, text)


SIGNATURE = re.compile(r"^(?:\d+\. )?(\w*)\((.*)\)(?: -> (.+))?$")  # a property's getter has no name


def parse_signature(line):
    """(name, [(parameter text)], return type) of a pybind11 signature line, or None."""
    m = SIGNATURE.match(line.strip())
    if not m:
        return None
    return m.group(1), split_top_level(m.group(2)), m.group(3) or "None"


def signatures(doc):
    """[(signature line parsed, docstring text)] of a pybind11 docstring (one per overload)."""
    lines = (doc or "").split("\n")
    if len(lines) > 1 and lines[1] == "Overloaded function.":  # pybind11 >= 2.6: name(*args, **kwargs) first
        lines = lines[1:]
    if lines and lines[0].endswith("Overloaded function."):
        result, current, body = [], None, []
        for line in lines[1:]:
            parsed = parse_signature(line) if re.match(r"^\d+\. ", line) else None
            if parsed:
                if current:
                    result.append((current, "\n".join(body).strip()))
                current, body = parsed, []
            elif current:
                body.append(line)
        if current:
            result.append((current, "\n".join(body).strip()))
        return result
    parsed = parse_signature(lines[0]) if lines else None
    return [(parsed, "\n".join(lines[1:]).strip())] if parsed else []


def parameter(text, first_is_self):
    """One parameter of a signature as stub text: `name: type = ...`, `*`, `*args: T`."""
    if text in ("*", "/"):
        return text
    default = ""
    head = text
    parts = split_top_level(text, "=")
    if len(parts) > 1:
        head, default = parts[0], " = ..."
    name, _, annotation = head.partition(":")
    name = name.strip()
    if first_is_self:
        return name
    return "%s: %s%s" % (name, stub_type(annotation) if annotation else "Any", default)


def docstring(text, indent):
    if not text:
        return []
    text = text.replace("\\", "\\\\").replace('"""', '\\"\\"\\"')
    lines = text.split("\n")
    out = [indent + '"""' + lines[0]]
    out += [(indent + line) if line.strip() else "" for line in lines[1:]]
    out[-1] += '"""'
    if len(lines) > 1:
        out[-1] = out[-1][: -3]
        out.append(indent + '"""')
    return out


def function_stub(name, doc, indent="", method=False, static=False):
    sigs = signatures(doc)
    if not sigs:
        raise SystemExit("gen_stubs: %s has no pybind11 signature in its docstring" % name)
    out = []
    for parsed, body in sigs:
        _, params, returns = parsed
        if len(sigs) > 1:
            out.append(indent + "@overload")
        if static:
            out.append(indent + "@staticmethod")
        text = [parameter(p, method and not static and i == 0) for i, p in enumerate(params)]
        out.append("%sdef %s(%s) -> %s:" % (indent, name, ", ".join(text), stub_type(returns)))
        out += docstring(body, indent + "    ")
        out.append(indent + "    ...")
    return out


def property_stub(name, prop, indent):
    sigs = signatures(prop.fget.__doc__) if prop.fget is not None else []
    returns = stub_type(sigs[0][0][2]) if sigs else "Any"
    body = inspect.cleandoc(prop.__doc__ or "") or (sigs[0][1] if sigs else "")
    out = [indent + "@property", "%sdef %s(self) -> %s:" % (indent, name, returns)]
    out += docstring(body, indent + "    ")
    out.append(indent + "    ...")
    if prop.fset is not None:
        out += [indent + "@%s.setter" % name, "%sdef %s(self, value: %s) -> None: ..." % (indent, name, returns)]
    return out


SKIPPED_MEMBERS = {"__doc__", "__module__", "__dict__", "__weakref__", "_pybind11_conduit_v1_"}


def class_stub(name, cls):
    out = ["class %s:" % name]
    out += docstring(inspect.cleandoc(cls.__doc__ or ""), "    ")
    for member, value in vars(cls).items():
        if member in SKIPPED_MEMBERS:
            continue
        if isinstance(value, property):
            out += property_stub(member, value, "    ")
        elif isinstance(value, staticmethod):
            out += function_stub(member, value.__func__.__doc__, "    ", method=True, static=True)
        elif callable(value) and signatures(getattr(value, "__doc__", None)):
            out += function_stub(member, value.__doc__, "    ", method=True)
        elif callable(value) and not member.startswith("__"):
            raise SystemExit("gen_stubs: %s.%s has no pybind11 signature in its docstring" % (name, member))
    if len(out) == 1:
        out.append("    ...")
    return out


def generate():
    module = importlib.import_module(MODULE)
    out = ['"""Type stubs of %s, written by scripts/gen_stubs.py from the module\'s signatures and' % MODULE,
           'docstrings (run it again after changing a binding; tests/python/test_stubs.py checks them)."""',
           "from typing import " + ", ".join(TYPING + ("overload",)), "", "import os", "", "import numpy", "",
           "__version__: str", ""]
    for name in sorted(n for n in dir(module) if not n.startswith("_")):
        value = getattr(module, name)
        if inspect.isclass(value):
            out += class_stub(name, value)
        elif callable(value):
            out += function_stub(name, value.__doc__)
        else:
            out.append("%s: %s" % (name, type(value).__name__))
        out.append("")
    return "\n".join(out).rstrip("\n") + "\n"


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("out", nargs="?", default=DEFAULT_OUT)
    p.add_argument("--check", action="store_true", help="exit 1 when OUT is not what would be written")
    a = p.parse_args(argv)
    text = generate()
    if a.check:
        with open(a.out, encoding="utf-8") as f:
            same = f.read() == text
        print("%s is %s" % (a.out, "up to date" if same else "out of date; run scripts/gen_stubs.py"))
        return 0 if same else 1
    tmp = a.out + ".tmp"
    with open(tmp, "w", encoding="utf-8") as f:
        f.write(text)
    os.replace(tmp, a.out)
    print("wrote " + a.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
