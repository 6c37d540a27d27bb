"""The type stubs python/wavebrdf/_core.pyi against the extension they describe: every public
name of wavebrdf._core (and every public member of its classes) has a stub, every stub names
something that exists, and each function's or method's parameter names are the extension's
(pybind11's signature line in the docstring). A failure lists the names that are missing or
extra; `PYTHONPATH=build/python /usr/bin/python3 scripts/gen_stubs.py` writes the stubs again."""
import ast
import inspect
import os
import re

import pytest

from conftest import ROOT

import wavebrdf._core as core

STUBS = os.path.join(ROOT, "python", "wavebrdf", "_core.pyi")
REGENERATE = "; run: PYTHONPATH=build/python /usr/bin/python3 scripts/gen_stubs.py"


def stub_tree():
    with open(STUBS, encoding="utf-8") as f:
        return ast.parse(f.read(), STUBS)


def stub_definitions(body):
    """{name: [ast node, ...]} of the definitions in a module's or class's body (overloads and
    property setters give several nodes per name)."""
    out = {}
    for node in body:
        if isinstance(node, (ast.FunctionDef, ast.ClassDef)):
            out.setdefault(node.name, []).append(node)
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            out.setdefault(node.target.id, []).append(node)
    return out


def split_parameters(text):
    """The parameters of a signature's argument list, split at top-level commas."""
    parts, depth, current, quote = [], 0, "", None
    for ch in text:
        if quote:
            quote = None if ch == quote else quote
        elif ch in "'\"":
            quote = ch
        elif ch in "([{<":
            depth += 1
        elif ch in ")]}>":
            depth -= 1
        elif ch == "," and depth == 0:
            parts.append(current.strip())
            current = ""
            continue
        current += ch
    return parts + ([current.strip()] if current.strip() else [])


def extension_parameter_lists(obj):
    """The parameter names of each overload of a pybind11 function, from `__text_signature__`
    where there is one, else from the signature lines of its docstring ('*' marks keyword-only)."""
    text_signature = getattr(obj, "__text_signature__", None)
    if text_signature:
        return [tuple(p.split("=")[0].split(":")[0].strip() for p in split_parameters(text_signature.strip()[1:-1]))]
    lines = (obj.__doc__ or "").split("\n")
    if len(lines) > 1 and lines[1] == "Overloaded function.":  # one line "N. name(...)" per overload
        found = [re.match(r"^\d+\. \w+\((.*)\)(?: -> .+)?$", line) for line in lines[2:]]
    else:  # the first line only: the docstring's text may show calls of its own
        found = [re.match(r"^\w*\((.*)\)(?: -> .+)?$", lines[0])]
    signatures = [m.group(1) for m in found if m]
    return [tuple(p.split("=")[0].split(":")[0].strip() for p in split_parameters(s)) for s in signatures]


def stub_parameter_list(node):
    a = node.args
    names = [p.arg for p in a.posonlyargs + a.args]
    if a.vararg:
        names.append("*" + a.vararg.arg)
    elif a.kwonlyargs:
        names.append("*")
    names += [p.arg for p in a.kwonlyargs]
    if a.kwarg:
        names.append("**" + a.kwarg.arg)
    return tuple(names)


def public_members(cls):
    """The members a stub must describe: properties and pybind11 methods (dunder ones included,
    except those every class has)."""
    out = {}
    for name, value in vars(cls).items():
        if name in ("__doc__", "__module__", "__dict__", "__weakref__") or name.startswith("_pybind11"):
            continue
        if name.startswith("_") and not name.startswith("__"):
            continue
        first_line = (getattr(value, "__doc__", None) or "").split("\n")[0]
        if isinstance(value, (property, staticmethod)) or re.match(r"^\w+\(.*\)( -> .+)?$", first_line):
            out[name] = value
    return out


def module_names():
    return {n for n in dir(core) if not n.startswith("_")} | {"__version__"}


def test_every_public_name_has_a_stub_and_every_stub_exists():
    stubs = stub_definitions(stub_tree().body)
    missing = sorted(module_names() - set(stubs))
    extra = sorted(n for n in set(stubs) if not hasattr(core, n))
    assert not missing and not extra, "_core.pyi: missing stubs for %s; stubs of names the module lacks: %s%s" % (
        missing, extra, REGENERATE)


def test_every_class_member_has_a_stub_and_every_member_stub_exists():
    stubs = stub_definitions(stub_tree().body)
    problems = []
    for name in sorted(module_names()):
        value = getattr(core, name)
        if not inspect.isclass(value) or name not in stubs:
            continue
        members = stub_definitions(stubs[name][0].body)
        wanted = set(public_members(value))
        for m in sorted(wanted - set(members)):
            problems.append("missing %s.%s" % (name, m))
        for m in sorted(set(members) - set(dir(value))):
            problems.append("extra %s.%s" % (name, m))
    assert not problems, "_core.pyi: " + ", ".join(problems) + REGENERATE


def test_parameter_names_match_the_extension():
    stubs = stub_definitions(stub_tree().body)
    problems = []

    def compare(label, obj, nodes, drop_self):
        wanted = extension_parameter_lists(obj)
        got = [stub_parameter_list(n) for n in nodes if isinstance(n, ast.FunctionDef)
               and not any(isinstance(d, ast.Attribute) and d.attr == "setter" for d in n.decorator_list)]
        if drop_self:
            got = [g[1:] for g in got]
            wanted = [w[1:] if w and w[0] == "self" else w for w in wanted]
        if sorted(got) != sorted(wanted):
            problems.append("%s: stub %s, extension %s" % (label, sorted(got), sorted(wanted)))

    for name in sorted(module_names()):
        value = getattr(core, name)
        if name not in stubs:
            continue  # reported by the test of names
        if inspect.isclass(value):
            members = stub_definitions(stubs[name][0].body)
            for m, member in sorted(public_members(value).items()):
                if m not in members or isinstance(member, property):
                    continue
                static = isinstance(member, staticmethod)
                compare("%s.%s" % (name, m), member.__func__ if static else member, members[m], not static)
        elif callable(value):
            compare(name, value, stubs[name], False)
    assert not problems, "_core.pyi parameter names differ: " + "; ".join(problems) + REGENERATE


def test_the_stubs_ship_with_the_package():
    """py.typed marks the package as typed (PEP 561); pyproject.toml ships both files."""
    package = os.path.join(ROOT, "python", "wavebrdf")
    assert os.path.isfile(os.path.join(package, "py.typed"))
    with open(os.path.join(ROOT, "pyproject.toml"), encoding="utf-8") as f:
        pyproject = f.read()
    assert '"py.typed"' in pyproject and '"*.pyi"' in pyproject


@pytest.mark.parametrize("name", ["invert", "Heightfield"])
def test_a_wrong_stub_is_detected(name, tmp_path):
    """The checks can fail: a stub with a renamed parameter or a missing class is reported."""
    tree = stub_tree()
    if name == "invert":
        node = stub_definitions(tree.body)["invert"][0]
        node.args.kwonlyargs[0].arg = "not_a_parameter"
        assert stub_parameter_list(node) not in extension_parameter_lists(core.invert)
    else:
        tree.body = [n for n in tree.body if getattr(n, "name", None) != "Heightfield"]
        assert "Heightfield" in module_names() - set(stub_definitions(tree.body))
