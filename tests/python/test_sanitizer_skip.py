"""tests/sanitizer_skip.txt kept honest: scripts/test.sh's sanitizer pass leaves the tests it
names to the Release pass, each with a lighter test that runs the same code under the
sanitizers. Every name must be a test of tests/*.cpp (a renamed test would otherwise run again
unnoticed, and a misspelt cover would cover nothing), and no cover may itself be skipped."""
import glob
import os
import re

from conftest import ROOT


def _tests():
    names = set()
    for path in glob.glob(os.path.join(ROOT, "tests", "*.cpp")):
        with open(path, encoding="utf-8") as f:
            for suite, name in re.findall(r"\bTEST(?:_F)?\((\w+),\s*(\w+)\)", f.read()):
                names.add(f"{suite}.{name}")
    return names


def _entries():
    with open(os.path.join(ROOT, "tests", "sanitizer_skip.txt"), encoding="utf-8") as f:
        return [line.split() for line in f if line.strip() and not line.startswith("#")]


def test_every_skipped_test_and_its_cover_exist():
    tests = _tests()
    entries = _entries()
    assert entries, "tests/sanitizer_skip.txt names no test"
    for entry in entries:
        assert len(entry) == 2, f"expected 'SKIPPED COVER', got {' '.join(entry)!r}"
        for name in entry:
            assert name in tests, f"{name} is not a test in tests/*.cpp"


def test_no_cover_is_itself_skipped():
    entries = _entries()
    skipped = {e[0] for e in entries}
    assert len(skipped) == len(entries), "a test is listed twice"
    for skipped_name, cover in entries:
        assert cover not in skipped, f"{skipped_name}'s cover {cover} is skipped too"


def test_the_sanitizer_pass_reads_the_list():
    with open(os.path.join(ROOT, "scripts", "test.sh"), encoding="utf-8") as f:
        script = f.read()
    assert "tests/sanitizer_skip.txt" in script and "-E" in script
