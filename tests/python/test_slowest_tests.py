"""scripts/slowest_tests.py: the slowest tests of a ctest log, slowest first."""
import os
import subprocess
import sys

import conftest

SCRIPT = os.path.join(conftest.ROOT, "scripts", "slowest_tests.py")

LOG = """Start testing: Nov 29 14:20 UTC
----------------------------------------------------------
1/3 Testing: Fast.One
Test command: /x/wavebrdf_tests "--gtest_filter=Fast.One"
Test time =   0.02 sec
----------------------------------------------------------
Test Passed.
2/3 Testing: Slow.Recovery
Test time =  42.86 sec
3/3 Testing: Middle.Two
Test time =   7.50 sec
"""


def test_the_slowest_come_first_with_their_times(tmp_path):
    log = tmp_path / "Testing" / "Temporary"
    log.mkdir(parents=True)
    (log / "LastTest.log").write_text(LOG)
    out = subprocess.run([sys.executable, SCRIPT, str(tmp_path), "2"], capture_output=True, text=True, check=True).stdout
    lines = out.splitlines()
    assert "the 2 slowest of 3 tests (50 s of test time summed)" in lines[0]
    assert lines[1].split() == ["42.86", "s", "Slow.Recovery"]
    assert lines[2].split() == ["7.50", "s", "Middle.Two"]


def test_a_missing_log_is_named(tmp_path):
    r = subprocess.run([sys.executable, SCRIPT, str(tmp_path)], capture_output=True, text=True)
    assert r.returncode == 1
    assert "LastTest.log" in r.stderr and "cannot read" in r.stderr
