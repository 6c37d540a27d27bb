#!/usr/bin/env python3
"""Chooses the tests that the sanitizer pass of scripts/test.sh leaves out, by line coverage.

The rule: a test is left out of the sanitizer pass only when it is slow there (at least
--min-seconds) and every line of our code it runs (src/, include/, apps/: the library, the CLI,
the plugins) is run by a test the pass keeps. From the slowest test down, each test whose lines
the kept tests cover is left out. Always kept: a test whose coverage could not be measured, and
every test docs/reliability.md names as a guarantee's proof (that page promises that they run
under the sanitizers). The Release pass runs every test either way.

Usage: python3 scripts/sanitizer_skip.py [--jobs N] [--min-seconds S] [--build DIR] [--check]
  1. configures and builds build-coverage/ (or DIR: clang with -fprofile-instr-generate -fcoverage-mapping,
     the sanitizer build's options otherwise);
  2. runs every test alone, N at once, each with its own profiles (LLVM_PROFILE_FILE: every process a
     test starts writes its own, the CLI and mpiexec's ranks included); a test whose merged profile
     is there from an earlier run is not run again (delete build-coverage/profiles to start over);
  3. reads each test's covered lines (llvm-cov export);
  4. chooses, and writes tests/sanitizer_skip.txt: each test left out with the kept test that runs
     most of its lines. --check writes nothing and exits 1 if the file differs from the choice.

The sanitizer pass's times come from build-sanitize/Testing/Temporary/LastTest.log (the last
sanitizer ctest run); a test missing there (it was left out) counts as its Release time
(build/Testing/Temporary/LastTest.log) times the 90th percentile of the ratios of the tests that
are in both.
"""
import argparse
import concurrent.futures
import os
import re
import shutil
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "scripts"))
import slowest_tests  # noqa: E402  (the LastTest.log reader)

BUILD = os.path.join(ROOT, "build-coverage")
PROFILES = os.path.join(BUILD, "profiles")
SKIP_FILE = os.path.join(ROOT, "tests", "sanitizer_skip.txt")
OUR_CODE = tuple(os.path.join(ROOT, d) + os.sep for d in ("src", "include", "apps"))
FLAGS = "-fprofile-instr-generate -fcoverage-mapping"


def fail(message):
    sys.stderr.write(f"sanitizer_skip: {message}\n")
    sys.exit(1)


def tool(name):
    for candidate in (name, f"{name}-14", f"{name}-15", f"{name}-16"):
        path = shutil.which(candidate)
        if path:
            return path
    fail(f"{name} not found (Debian: llvm)")


def build(jobs):
    if not shutil.which("clang++"):
        fail("clang++ not found (Debian: clang)")
    env = dict(os.environ, CC="clang", CXX="clang++")
    configure = ["cmake", "-S", ROOT, "-B", BUILD, "-DCMAKE_BUILD_TYPE=RelWithDebInfo",
                 "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O1 -g0 -DNDEBUG", "-DCMAKE_C_FLAGS_RELWITHDEBINFO=-O1 -g0 -DNDEBUG",
                 f"-DCMAKE_CXX_FLAGS={FLAGS}", f"-DCMAKE_C_FLAGS={FLAGS}",
                 "-DCMAKE_EXE_LINKER_FLAGS=-fprofile-instr-generate",
                 "-DCMAKE_SHARED_LINKER_FLAGS=-fprofile-instr-generate",
                 "-DCMAKE_MODULE_LINKER_FLAGS=-fprofile-instr-generate",
                 "-DWAVEBRDF_SHARED=ON", "-DWAVEBRDF_BUILD_BENCH=OFF", "-DWAVEBRDF_BUILD_PYTHON=OFF",
                 "-DWAVEBRDF_BUILD_EXPERIMENTS=OFF", "-DWAVEBRDF_UNITY_BUILD=ON", "-DWAVEBRDF_TESTS_OPT="]
    if shutil.which("ccache"):
        configure += ["-DCMAKE_C_COMPILER_LAUNCHER=ccache", "-DCMAKE_CXX_COMPILER_LAUNCHER=ccache"]
    subprocess.run(configure, env=env, check=True, stdout=subprocess.DEVNULL)
    subprocess.run(["cmake", "--build", BUILD, f"-j{jobs}"], check=True)


def test_names():
    out = subprocess.run(["ctest", "-N"], cwd=BUILD, check=True, capture_output=True, text=True).stdout
    return re.findall(r"^\s*Test\s+#\d+: (\S+)$", out, re.M)


def safe(name):
    return re.sub(r"[^A-Za-z0-9_.-]", "_", name)


def run_one(name, profdata_tool):
    """Runs one test with its own profiles and merges them; returns (name, ok)."""
    merged = os.path.join(PROFILES, safe(name) + ".profdata")
    if os.path.exists(merged):
        return name, True
    raw = os.path.join(PROFILES, safe(name))
    shutil.rmtree(raw, ignore_errors=True)
    os.makedirs(raw)
    env = dict(os.environ, OMP_WAIT_POLICY="passive",
               LLVM_PROFILE_FILE=os.path.join(raw, "%p-%m.profraw"))
    pattern = "^" + re.escape(name) + "$"
    result = subprocess.run(["ctest", "-R", pattern, "--output-on-failure"], cwd=BUILD, env=env,
                            capture_output=True, text=True)
    files = [os.path.join(raw, f) for f in os.listdir(raw) if f.endswith(".profraw")]
    if result.returncode != 0 or not files:
        sys.stderr.write(f"sanitizer_skip: {name} failed or wrote no profile; it stays in the pass\n")
        return name, False
    subprocess.run([profdata_tool, "merge", "-sparse", "-o", merged + ".part", *files], check=True)
    os.replace(merged + ".part", merged)
    shutil.rmtree(raw)
    return name, True


def instrumented_objects():
    """Our binaries that carry coverage mappings: the CLI, the tests, the library, the plugins."""
    found = []
    for top, _, files in os.walk(BUILD):
        if os.sep + "CMakeFiles" in top or top.startswith(PROFILES):
            continue
        for f in files:
            path = os.path.join(top, f)
            if os.path.islink(path) or not os.access(path, os.X_OK) and ".so" not in f:
                continue
            with open(path, "rb") as fh:
                head = fh.read(4)
                if head != b"\x7fELF":
                    continue
                if b"__llvm_covmap" in fh.read():
                    found.append(path)
    return sorted(found)


def covered_lines(name, cov_tool, objects):
    """The (file, line) pairs of our code the test ran."""
    merged = os.path.join(PROFILES, safe(name) + ".profdata")
    args = [cov_tool, "export", "-format=lcov", "-skip-functions", f"-instr-profile={merged}", objects[0]]
    args += [f"-object={o}" for o in objects[1:]]
    out = subprocess.run(args, check=True, capture_output=True, text=True).stdout
    lines = set()
    source = None
    for row in out.splitlines():
        if row.startswith("SF:"):
            path = os.path.realpath(row[3:])
            source = path if path.startswith(OUR_CODE) else None
        elif source is not None and row.startswith("DA:"):
            line, count = row[3:].split(",")[:2]
            if int(count) > 0:
                lines.add((source, int(line)))
    return name, lines


def sanitizer_seconds(names):
    """Each test's time in the sanitizer pass (measured, or estimated from its Release time)."""
    def read(build_dir):
        log = os.path.join(ROOT, build_dir, "Testing", "Temporary", "LastTest.log")
        try:
            with open(log, encoding="utf-8", errors="replace") as f:
                top, _, _ = slowest_tests.slowest(f.read(), 10 ** 6)
        except OSError as e:
            fail(f"cannot read {log}: {e.strerror} (run scripts/test.sh first)")
        return {n: t for t, n in top}
    sanitizer, release = read("build-sanitize"), read("build")
    # A test the pass did not run is taken as slow there (the 90th percentile of the ratios, not the
    # median): recoveries run 10-15 times their Release time under the sanitizers, the rest 2-5
    # times, and an untimed test taken as cheap would be kept in place of a timed one.
    ratios = sorted(sanitizer[n] / release[n] for n in sanitizer if release.get(n, 0) > 0.5)
    ratio = ratios[int(0.9 * (len(ratios) - 1))] if ratios else 10.0
    return {n: sanitizer.get(n, release.get(n, 0.0) * ratio) for n in names}


def reliability_tests(names):
    """The tests docs/reliability.md names as proofs (its "Test time" section only quotes timings)."""
    with open(os.path.join(ROOT, "docs", "reliability.md"), encoding="utf-8") as f:
        text = f.read()
    text = re.sub(r"^## Test time\n.*?(?=^## )", "", text, flags=re.S | re.M)
    return set(re.findall(r"\b(\w+\.\w+)\b", text)) & set(names)


def choose(lines, seconds, min_seconds, always_kept=frozenset()):
    """Left out: from the slowest down, each slow test whose lines the kept tests all run."""
    runs = {}  # line -> how many kept tests run it
    for covered in lines.values():
        for line in covered:
            runs[line] = runs.get(line, 0) + 1
    kept = set(lines)
    left_out = []
    for name in sorted(lines, key=lambda n: (-seconds[n], n)):
        if seconds[name] < min_seconds:
            break
        if name not in always_kept and all(runs[line] > 1 for line in lines[name]):
            kept.discard(name)
            left_out.append(name)
            for line in lines[name]:
                runs[line] -= 1
    return left_out, kept


def cover_of(name, lines, kept):
    """The kept test (of those measured) that runs most of name's lines."""
    return max(sorted(kept & lines.keys()), key=lambda n: len(lines[name] & lines[n]))


def skip_file_text(left_out, lines, kept, seconds, min_seconds):
    saved = sum(seconds[n] for n in left_out)
    head = [
        "# Tests that the sanitizer pass of scripts/test.sh (ASan + UBSan) does not run; the Release pass",
        "# runs every test. Written by scripts/sanitizer_skip.py, by line coverage: a test is left out",
        f"# only when it takes at least {min_seconds:g} s in the sanitizer pass and every line of src/,",
        "# include/ and apps/ it runs is run by a test the pass keeps. After the name, the kept test that",
        "# runs most of its lines. Rerun the script when tests or the code they run change.",
        f"# {len(left_out)} tests, about {saved:.0f} s of the sanitizer pass's test time (a test that did not",
        "# run there counted as its Release time times the 90th percentile of the ratios of those that did).",
    ]
    body = [f"{n}  {cover_of(n, lines, kept)}" for n in sorted(left_out)]
    return "\n".join(head + body) + "\n"


def main(argv):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    parser.add_argument("--min-seconds", type=float, default=2.0)
    parser.add_argument("--check", action="store_true")
    parser.add_argument("--build", default=os.path.join(ROOT, "build-coverage"), help="the coverage build's folder (default build-coverage)")
    args = parser.parse_args(argv[1:])
    global BUILD, PROFILES
    BUILD = os.path.abspath(args.build)
    PROFILES = os.path.join(BUILD, "profiles")
    if not 1 <= args.jobs <= 256:
        fail(f"--jobs {args.jobs}: expected 1 to 256")
    if not 0 <= args.min_seconds <= 3600:
        fail(f"--min-seconds {args.min_seconds}: expected 0 to 3600")
    profdata_tool, cov_tool = tool("llvm-profdata"), tool("llvm-cov")
    build(args.jobs)
    names = test_names()
    os.makedirs(PROFILES, exist_ok=True)
    measured = []
    with concurrent.futures.ThreadPoolExecutor(args.jobs) as pool:
        for done, (name, ok) in enumerate(pool.map(lambda n: run_one(n, profdata_tool), names), 1):
            if ok:
                measured.append(name)
            if done % 50 == 0 or done == len(names):
                print(f"sanitizer_skip: {done}/{len(names)} tests run", flush=True)
    objects = instrumented_objects()
    with concurrent.futures.ThreadPoolExecutor(args.jobs) as pool:
        lines = dict(pool.map(lambda n: covered_lines(n, cov_tool, objects), measured))
    seconds = sanitizer_seconds(names)
    left_out, kept = choose(lines, seconds, args.min_seconds, reliability_tests(names))
    text = skip_file_text(left_out, lines, kept, seconds, args.min_seconds)
    with open(SKIP_FILE, encoding="utf-8") as f:
        same = f.read() == text
    if args.check:
        print(f"sanitizer_skip: {SKIP_FILE} {'agrees with' if same else 'differs from'} the coverage")
        return 0 if same else 1
    with open(SKIP_FILE + ".part", "w", encoding="utf-8") as f:
        f.write(text)
    os.replace(SKIP_FILE + ".part", SKIP_FILE)
    print(f"sanitizer_skip: {len(left_out)} tests left out of the sanitizer pass "
          f"({sum(seconds[n] for n in left_out):.0f} of {sum(seconds.values()):.0f} s); {SKIP_FILE} written")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
