"""tests/sanitizer_skip.txt kept honest: scripts/test.sh's sanitizer pass leaves the tests it
names to the Release pass, each with the kept test that runs most of its lines
(scripts/sanitizer_skip.py chooses them by line coverage). Every name must be a test of
tests/*.cpp (a renamed test would otherwise run again unnoticed, and a misspelt cover would
cover nothing), no cover may itself be skipped, and no test docs/reliability.md names as a
guarantee's proof may be skipped. The choice itself is checked on small coverage maps."""
import glob
import os
import re
import sys

from conftest import ROOT

sys.path.insert(0, os.path.join(ROOT, "scripts"))
import sanitizer_skip  # noqa: E402


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


def test_no_test_that_reliability_names_is_skipped():
    skipped = {e[0] for e in _entries()}
    named = sanitizer_skip.reliability_tests(_tests())
    assert named, "docs/reliability.md names no test"
    assert not skipped & named, f"skipped, though docs/reliability.md names them: {sorted(skipped & named)}"


def test_a_test_is_left_out_only_when_the_kept_tests_run_all_its_lines():
    lines = {"slow": {1, 2, 3}, "mid": {2, 3, 4}, "fast": {1, 4}, "own": {5}}
    seconds = {"slow": 30.0, "mid": 10.0, "fast": 0.5, "own": 20.0}
    left_out, kept = sanitizer_skip.choose(lines, seconds, min_seconds=2.0)
    # slow's lines are all run by mid and fast; then mid's line 3 is run by no other kept test.
    assert left_out == ["slow"]
    assert kept == {"mid", "fast", "own"}
    # A test under the time limit stays, even when others run its lines.
    assert sanitizer_skip.choose(lines, dict(seconds, slow=1.0), min_seconds=2.0)[0] == ["mid"]
    # A test that must run under the sanitizers stays; the next slowest goes instead.
    assert sanitizer_skip.choose(lines, seconds, 2.0, always_kept={"slow"})[0] == ["mid"]
    # Every line the whole suite runs is still run by the kept tests.
    assert set().union(*(lines[n] for n in kept)) == set().union(*lines.values())
