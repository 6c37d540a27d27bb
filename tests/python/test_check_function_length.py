"""scripts/check_function_length.py: no function in src/ over 200 lines, and the scan it rests on."""
import os
import subprocess
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
SCRIPT = os.path.join(ROOT, "scripts", "check_function_length.py")
sys.path.insert(0, os.path.join(ROOT, "scripts"))
import check_function_length as checker  # noqa: E402


def body(lines):
    """Statements filling `lines` lines."""
    return "".join(f"    x += {k};\n" for k in range(lines))


def function(name, lines, signature_lines=1):
    """A function of exactly `lines` lines (signature, body, closing brace)."""
    assert lines >= signature_lines + 2
    head = f"int {name}(int x" + "".join(f",\n    int a{k}" for k in range(signature_lines - 1)) + ") {\n"
    return head + body(lines - signature_lines - 2) + "    return x;\n}\n"


def run(root, *extra):
    return subprocess.run([sys.executable, SCRIPT, *extra, str(root)], capture_output=True, text=True)


def tree(tmp_path, text, name="a.cpp"):
    (tmp_path / "src" / "stage").mkdir(parents=True, exist_ok=True)
    (tmp_path / "src" / "stage" / name).write_text(text)
    return tmp_path


def test_the_repository_has_no_function_over_the_limit():
    r = run(ROOT)
    assert r.returncode == 0, r.stdout + r.stderr


def test_lengths_count_from_the_signature_to_the_closing_brace():
    text = "namespace n {\n\n" + function("f", 30, signature_lines=3) + "\n" + function("g", 7) + "}\n"
    found = checker.functions(text)
    assert [(name, last - first + 1) for first, last, name in found] == [("f", 30), ("g", 7)]
    assert found[0][0] == 3  # f's signature starts on line 3


def test_a_function_over_the_limit_fails_and_is_named(tmp_path):
    root = tree(tmp_path, "namespace n {\n" + function("short_one", 200) + function("too_long", 201) + "}\n")
    r = run(root)
    assert r.returncode == 1
    lines = r.stdout.splitlines()
    assert len(lines) == 1, r.stdout
    assert "src/stage/a.cpp:" in lines[0] and "too_long is 201 lines" in lines[0]
    assert run(root, "--limit", "201").returncode == 0


def test_braces_in_comments_literals_and_preprocessor_lines_are_not_code():
    noisy = (
        "#define OPEN {\n"
        "#define CLOSE \\\n    }\n"
        "int noisy(int x) {\n"
        "    // } a closing brace in a comment\n"
        "    /* { and } in\n       a block comment */\n"
        "    const char* s = \"}}\\\"{\";\n"
        "    const char c = '}', d = '\\'';\n"
        "    const char* raw = R\"x(}\" })x\";\n"
        "    const int big = 1'000'000;\n"
        "    return x + big;\n"
        "}\n"
    )
    text = "namespace n {\n" + noisy + function("after", 12) + "}  // namespace n\n"
    found = checker.functions(text)
    assert [(name, last - first + 1) for first, last, name in found] == [("noisy", 10), ("after", 12)]


def test_members_lambdas_and_tables():
    text = (
        "namespace n {\n"
        "constexpr int table[] = {\n" + "".join(f"    {k},\n" for k in range(300)) + "};\n"
        "class Fit {\n"
        "public:\n"
        "    double loss(int x) const {\n"
        "        auto f = [&](int y) {\n"
        "            return y;\n"
        "        };\n"
        "        return f(x);\n"
        "    }\n"
        "};\n"
        "double Fit::other(int x) {\n"
        "    if (x) {\n"
        "        return 1;\n"
        "    }\n"
        "    return 0;\n"
        "}\n"
        "}\n"
    )
    found = checker.functions(text)
    assert [(name, last - first + 1) for first, last, name in found] == [("loss", 6), ("Fit::other", 6)]


def test_bad_arguments_are_refused(tmp_path):
    r = run(tmp_path)
    assert r.returncode == 2 and "no src/ folder" in r.stderr
    r = run(ROOT, "--limit", "0")
    assert r.returncode == 2 and "--limit 0" in r.stderr


if __name__ == "__main__":
    sys.exit(pytest.main([__file__, "-q"]))
