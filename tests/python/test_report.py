"""Tests for the report plotters of the Python package: `python3 -m wavebrdf.report DIR` on an
inversion's and a recovery's run directory (wavebrdf.report, report_invert, report_recover).
Run: PYTHONPATH=build/python /usr/bin/python3 -m pytest -q tests/python/test_report.py"""
import json
import os
import subprocess
import sys

import numpy as np
import pytest

import conftest
from wavebrdf import report  # noqa: E402
from wavebrdf import report_invert as pi  # noqa: E402
from wavebrdf import report_recover as pr  # noqa: E402
import matplotlib.image as mpimg  # noqa: E402

PYTHON_DIR = os.path.join(conftest.BUILD, "python")


def run_module(*args, env_extra=None):
    """`python3 -m wavebrdf.report ARGS` in a fresh interpreter with the build's package."""
    env = dict(os.environ, PYTHONPATH=PYTHON_DIR, **(env_extra or {}))
    return subprocess.run([sys.executable, "-m", "wavebrdf.report", *map(str, args)], capture_output=True,
                          text=True, timeout=120, env=env)


PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
HEADER = "epoch,loss,brdf_mse,cmsle_1,cmsle_0.001,rgb_mse,rgb_gamma_mse,height_mse,seconds"


def build_dir(root, channels=3, truth=True, epochs=(0, 10, 30), n=16, size=24, all_epochs=(0, 10, 30, 100, 300),
              n_rows=31):
    """A synthetic `wavebrdf invert --out` directory with random data."""
    rng = np.random.default_rng(channels * 10 + truth)
    d = root / ("run_c%d_%s" % (channels, "truth" if truth else "notruth"))
    (d / "snapshots").mkdir(parents=True)
    (d / "run.json").write_text(json.dumps({
        "title": "synthetic %d-channel run" % channels, "snapshot_epochs": list(all_epochs),
        "channels": channels, "resolution": n, "texel_um": 0.5, "truth": truth, "ignored": [1, 2]}))
    lines = [HEADER]
    for e in range(n_rows):
        decay = np.exp(-e / 10.0)
        vals = [decay * rng.uniform(0.5, 2.0) for _ in range(6)]
        hm = "nan" if not truth else repr(0.3 * decay + 0.01)
        lines.append(",".join([str(e)] + [repr(v) for v in vals] + [hm, repr(0.1 * e)]))
    (d / "metrics.csv").write_text("\n".join(lines) + "\n")
    if truth:
        np.save(d / "truth_height.npy", rng.normal(0, 0.2, (size, size)))
    np.save(d / "reference.npy", rng.exponential(1.0, (n, n, channels)))
    for e in epochs:
        np.save(d / "snapshots" / ("height_%04d.npy" % e), rng.normal(0, 0.1, (size, size)))
        np.save(d / "snapshots" / ("slice_%04d.npy" % e), rng.exponential(1.0, (n, n, channels)))
        np.save(d / "snapshots" / ("gradient_%04d.npy" % e), rng.normal(0, 1e-3, (size, size)))
    return d


def check_png(path, min_w, min_h):
    assert os.path.isfile(path)
    with open(path, "rb") as f:
        assert f.read(8) == PNG_MAGIC
    img = mpimg.imread(path)
    h, w = img.shape[:2]
    assert min_w <= w <= 4000 and min_h <= h <= 4000, (w, h)
    # Not a blank canvas.
    assert float(np.ptp(img[..., :3])) > 0.2
    return w, h


@pytest.mark.parametrize("channels,truth", [(1, True), (3, True), (3, False)])
def test_report_and_curves(tmp_path, channels, truth):
    d = build_dir(tmp_path, channels=channels, truth=truth)
    report = pi.make_report(str(d))
    curves = pi.make_curves(str(d))
    assert report == os.path.join(str(d), "report.png")
    assert curves == os.path.join(str(d), "curves.png")
    w, h = check_png(report, 500, 800)
    assert h > w  # five rows of three columns
    check_png(curves, 500, 350)
    # No temporary files left behind.
    assert sorted(p.name for p in d.iterdir() if p.name.startswith(".")) == []


def test_main_writes_both_and_prints_paths(tmp_path, capsys):
    d = build_dir(tmp_path, channels=1, truth=False)
    assert report.main([str(d)]) == 0
    out = capsys.readouterr().out.split()
    assert out == [os.path.join(str(d), "report.png"), os.path.join(str(d), "curves.png")]
    for p in out:
        check_png(p, 300, 300)


def test_command_line(tmp_path):
    d = build_dir(tmp_path, channels=3, truth=True, epochs=(0, 10, 30, 100, 300), n=64, size=256)
    r = run_module(d)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == [str(d / "report.png"), str(d / "curves.png")]
    w, h = check_png(str(d / "report.png"), 1000, 1000)
    assert w < 2500 and h < 2500


def test_missing_metrics_exit_2(tmp_path, capsys):
    d = build_dir(tmp_path, channels=3, truth=True)
    os.remove(d / "metrics.csv")
    assert report.main([str(d)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "metrics.csv" in err[0]
    assert not (d / "report.png").exists() and not (d / "curves.png").exists()
    r = run_module(d)
    assert r.returncode == 2 and "metrics.csv" in r.stderr and r.stdout == ""


def test_missing_dir_exit_2(tmp_path, capsys):
    missing = tmp_path / "nope"
    assert report.main([str(missing)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(missing) in err[0]


def test_interrupted_run(tmp_path):
    """Only some snapshots, a missing gradient, a torn .npy, a partial last CSV line."""
    d = build_dir(tmp_path, channels=1, truth=True, epochs=(0, 10))
    os.remove(d / "snapshots" / "gradient_0010.npy")
    (d / "snapshots" / "slice_0010.npy").write_bytes(b"\x93NUMPY garbage")
    with open(d / "metrics.csv", "a") as f:
        f.write("31,0.1,0.2")
    assert report.main([str(d)]) == 0
    check_png(str(d / "report.png"), 300, 600)
    check_png(str(d / "curves.png"), 300, 300)


def test_no_snapshots_no_reference(tmp_path):
    d = build_dir(tmp_path, channels=3, truth=False, epochs=())
    os.remove(d / "reference.npy")
    os.remove(d / "run.json")
    assert report.main([str(d)]) == 0
    check_png(str(d / "report.png"), 200, 200)


def test_read_metrics_normalisation(tmp_path):
    d = build_dir(tmp_path, channels=3, truth=False)
    header, cols = pi.read_metrics(str(d))
    assert header == HEADER.split(",")
    assert len(cols["epoch"]) == 31 and cols["epoch"][0] == 0
    assert np.isnan(cols["height_mse"]).all()


def test_tonemap():
    ref = np.zeros((8, 8, 1))
    ref[3, 4] = 10.0
    scale = pi.tonemap_scale(ref)
    assert np.percentile(ref, 99.9) * scale == pytest.approx(4.0)
    img = pi.tonemap(ref, scale)
    assert img.shape == (8, 8)
    assert img[0, 0] == 0.0
    x = 10.0 * scale
    assert img[3, 4] == pytest.approx((x / (1 + x)) ** (1 / 2.2))
    assert 0 < img.max() < 1
    rgb = pi.tonemap(np.ones((4, 4, 3)), 1.0)
    assert rgb.shape == (4, 4, 3)
    assert rgb[0, 0, 0] == pytest.approx(0.5 ** (1 / 2.2))
    err = pi.squared_error(np.ones((4, 4, 3)), np.zeros((4, 4, 3)))
    assert err.shape == (4, 4) and (err == 3.0).all()


# ----------------------------------------------------------------------------------------------
# Recovery runs (wavebrdf recover --out DIR) and the dispatch by kind
# ----------------------------------------------------------------------------------------------
RECOVER_HEADER = "stage,iteration,loss,seconds,height_rel_rmse"


def build_recover_dir(root, channels=1, truth=True, n=16, size=12):
    """A synthetic `wavebrdf recover --out` directory (recovery_directory.h's layout)."""
    rng = np.random.default_rng(7 + channels + truth)
    d = root / ("recover_c%d_%s" % (channels, "truth" if truth else "notruth"))
    d.mkdir(parents=True)
    (d / "run.json").write_text(json.dumps({
        "method": "pipeline", "size": "%dx%d" % (size, size), "texel_um": 2.0, "vscale": 1.0,
        "height_range_um": 0.1, "noise": "none", "loss": "amplitude", "seed": 3, "observations": 9,
        "plan": ["3x3 positions", "one wavelength 0.5 um"], "warnings": ["a warning"], "truth": truth}))
    rows, t = [RECOVER_HEADER], 0.0
    for stage, count in (("blur:4", 5), ("blur", 1), ("field:0.5", 8), ("unwrap", 1), ("refine", 6)):
        for it in range(1, count + 1):
            t += 0.01
            err = repr(0.5 / it) if truth else "nan"
            loss = "0" if stage in ("blur", "unwrap") else repr(1.0 / it)
            rows.append("%s,%d,%s,%r,%s" % (stage, it, loss, t, err))
    (d / "metrics.csv").write_text("\n".join(rows) + "\n")
    np.save(d / "estimate_height.npy", rng.normal(0, 0.02, (size, size)))
    if truth:
        np.save(d / "truth_height.npy", rng.normal(0, 0.02, (size, size)))
    np.save(d / "reference.npy", rng.exponential(1.0, (n, n, channels)))
    np.save(d / "final.npy", rng.exponential(1.0, (n, n, channels)))
    return d


def no_temporaries(d):
    return [p.name for p in d.rglob("*") if ".tmp" in p.name] == []


def test_run_kind_from_the_metrics_header(tmp_path):
    assert report.run_kind(str(build_dir(tmp_path))) == "invert"
    assert report.run_kind(str(build_recover_dir(tmp_path))) == "recover"
    odd = tmp_path / "odd"
    odd.mkdir()
    (odd / "metrics.csv").write_text("time,value\n1,2\n")
    with pytest.raises(ValueError, match="'time'"):
        report.run_kind(str(odd))
    r = run_module(odd)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and "'time'" in r.stderr
    assert not (odd / "report.png").exists()


@pytest.mark.parametrize("channels,truth", [(1, True), (3, True), (1, False)])
def test_recover_report(tmp_path, channels, truth):
    d = build_recover_dir(tmp_path, channels=channels, truth=truth)
    assert pr.make_report(str(d)) == os.path.join(str(d), "report.png")
    w, h = check_png(str(d / "report.png"), 800, 400)
    assert w > h  # two rows of four panels
    assert no_temporaries(d)


def test_module_draws_a_recovery_and_prints_only_its_report(tmp_path):
    d = build_recover_dir(tmp_path)
    r = run_module(d)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == [str(d / "report.png")]
    assert not (d / "curves.png").exists()
    check_png(str(d / "report.png"), 800, 400)
    # It used to leave "report.png.tmp.png" on a failure; the temporary is now a hidden
    # ".report.png.XXXX.tmp" and nothing is left either way.
    assert no_temporaries(d)
    q = run_module("--quiet", d)
    assert (q.returncode, q.stdout, q.stderr) == (0, "", "")


def test_failed_write_leaves_no_temporary(tmp_path):
    d = build_recover_dir(tmp_path)
    # A directory where the PNG would go: os.replace fails after the temporary was written.
    (d / "report.png").mkdir()
    with pytest.raises(OSError):
        pr.make_report(str(d))
    assert no_temporaries(d)
    assert (d / "report.png").is_dir()


@pytest.mark.parametrize("missing,status", [("numpy", 3), ("matplotlib", 4)])
def test_missing_dependency_is_named_or_only_an_exit_status(tmp_path, missing, status):
    d = build_recover_dir(tmp_path)
    # A package of that name that cannot be imported, first on the path.
    fake = tmp_path / "fake" / missing
    fake.mkdir(parents=True)
    (fake / "__init__.py").write_text("raise ImportError('no %s here (test)')\n" % missing)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(tmp_path / "fake"), PYTHON_DIR]))
    loud = subprocess.run([sys.executable, "-m", "wavebrdf.report", str(d)], capture_output=True, text=True,
                          timeout=120, env=env)
    assert loud.returncode == status
    assert loud.stderr.strip().splitlines() == ["wavebrdf.report: error: %s is not installed for %s"
                                                % (missing, sys.executable)]
    quiet = subprocess.run([sys.executable, "-m", "wavebrdf.report", "--quiet", str(d)], capture_output=True,
                           text=True, timeout=120, env=env)
    assert (quiet.returncode, quiet.stdout, quiet.stderr) == (status, "", "")
    assert not (d / "report.png").exists()


def test_report_of_a_real_recover_run(cli, tmp_path):
    out = tmp_path / "run"
    subprocess.run([cli, "recover", "--size", "8", "--texel-um", "2", "--sigma-p-um", "3", "--height-range-um",
                    "0.1", "--seed", "3", "--method", "thesis", "--epochs", "20", "--no-plots", "--quiet",
                    "--out", str(out)], check=True)
    assert not (out / "report.png").exists()
    r = run_module(out)
    assert r.returncode == 0, r.stderr
    check_png(str(out / "report.png"), 800, 400)
