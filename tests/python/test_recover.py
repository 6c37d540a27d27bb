"""Heightfield recovery from Python: recover() recovers a small study and is the same run as
`wavebrdf recover` (same options and seed, same estimate), recovers from the CLI's saved
observations; the plan's positions overlap as stated, its slices and wavelengths follow its
rules; noise has the stated statistics; callbacks stop runs; bad arguments name themselves.

The CLI comparison runs both sides on one thread: the library's multi-threaded reductions
(schedule(dynamic) over observations) make two runs of the same command differ at ~1e-5."""
import csv
import json
import math
import os
import subprocess
import sys

import numpy as np
import pytest

import wavebrdf as wb

import conftest

# The small study of tests/recover_cli_test.cpp: 8x8 texels of 2 um, heights within 0.1 um
# (one wavelength suffices), sigma_p = 3 um.
SMALL = dict(size=8, texel_um=2.0, sigma_p_um=3.0, height_range_um=0.1, seed=3)
SMALL_CLI = ["--size", "8", "--texel-um", "2", "--sigma-p-um", "3", "--height-range-um", "0.1", "--seed", "3"]
ONE_THREAD = dict(os.environ, OMP_NUM_THREADS="1")


def rel_rmse(estimate_um, truth_um):
    """height_rel_rmse in NumPy: RMS error after removing the means, over the truth's range."""
    e = estimate_um - estimate_um.mean()
    t = truth_um - truth_um.mean()
    return np.sqrt(np.mean((e - t) ** 2)) / (truth_um.max() - truth_um.min())


@pytest.fixture(scope="module")
def cli_run(tmp_path_factory):
    """`wavebrdf recover` on the small study, one thread, with its observations saved."""
    out = tmp_path_factory.mktemp("recover") / "run"
    cli = os.path.join(conftest.BUILD, "bin", "wavebrdf")
    assert os.path.exists(cli), "%s is missing; build the wavebrdf_cli target" % cli
    subprocess.run([cli, "recover", *SMALL_CLI, "--save-observations", "--no-plots", "--quiet", "--out", str(out)],
                   check=True, env=ONE_THREAD)
    return out


def test_small_study_recovers_the_truth_as_the_cli_does(cli_run, tmp_path):
    # The same recover() in a fresh interpreter on one thread (as the CLI ran).
    saved = tmp_path / "py.npz"
    script = (
        "import numpy as np, json, wavebrdf as wb\n"
        "r = wb.recover(**%r)\n"
        "np.savez(%r, estimate=r.estimate.values, estimate_um=r.estimate.heights_um(), truth=r.truth.values,\n"
        "         truth_um=r.truth.heights_um(), texel=r.estimate.texel_um, stopped=r.stopped,\n"
        "         text=json.dumps(dict(notes=r.notes, warnings=r.warnings, loss=r.loss, method=r.method,\n"
        "                              noise=r.noise, observations=len(r.observations))),\n"
        "         **{'m_' + k: v for k, v in r.metrics.items()})\n" % (SMALL, str(saved)))
    env = dict(ONE_THREAD, PYTHONPATH=os.path.join(conftest.BUILD, "python"))
    subprocess.run([sys.executable, "-c", script], check=True, env=env)
    py = np.load(saved)

    # It recovers the truth (evaluated here, independently of the run's own metrics).
    assert rel_rmse(py["estimate_um"], py["truth_um"]) < 0.01
    assert py["texel"] == 2.0 and not py["stopped"]
    assert py["m_height_rel_rmse"][-1] == pytest.approx(rel_rmse(py["estimate_um"], py["truth_um"]), rel=1e-9, abs=1e-15)

    # The same truth and estimate as the CLI: its float64 .npy to 1e-9, its float EXRs to float rounding.
    cli_estimate_um = np.load(cli_run / "estimate_height.npy")
    np.testing.assert_allclose(py["estimate_um"], cli_estimate_um, rtol=0, atol=1e-9 * np.abs(cli_estimate_um).max())
    np.testing.assert_allclose(py["truth_um"], np.load(cli_run / "truth_height.npy"), rtol=1e-12, atol=0)
    for name, values in [("estimate.exr", py["estimate"]), ("truth.exr", py["truth"])]:
        from_exr = wb.Heightfield.from_exr(str(cli_run / name), 2.0).values
        np.testing.assert_allclose(values, from_exr, rtol=0, atol=2.0 ** -23 * np.abs(from_exr).max(), err_msg=name)

    # The same metrics stream (metrics.csv keeps 10 digits, height_rel_rmse 6 decimals).
    with open(cli_run / "metrics.csv") as f:
        rows = list(csv.DictReader(f))
    assert list(py["m_stage"]) == [r["stage"] for r in rows]
    np.testing.assert_array_equal(py["m_iteration"], [int(r["iteration"]) for r in rows])
    np.testing.assert_allclose(py["m_loss"], [float(r["loss"]) for r in rows], rtol=1e-8, atol=1e-300)
    np.testing.assert_allclose(py["m_height_rel_rmse"], [float(r["height_rel_rmse"]) for r in rows], rtol=0,
                               atol=1e-6)
    assert np.isnan(py["m_height_rel_rmse"][0])  # blur iterations: no heights reported yet
    run = json.load(open(cli_run / "run.json"))
    text = json.loads(str(py["text"]))
    assert text["notes"] == run["plan"] and text["warnings"] == run["warnings"]
    assert (text["loss"], text["noise"], text["method"]) == (run["loss"], run["noise"], run["method"])
    assert text["observations"] == run["observations"]


def test_recover_heights_with_defaults_runs_the_cli_schedule(cli_run, tmp_path):
    """recover_heights with its default settings, on recover()'s observations, runs the schedule
    that recover() and `wavebrdf recover` run for this smooth surface (recover.h,
    scheduled_settings): the same heights, bit for bit, from all three (one thread each, as the
    CLI ran). The front ends used to overwrite the settings with a schedule of their own."""
    saved = tmp_path / "defaults.npz"
    script = (
        "import numpy as np, wavebrdf as wb\n"
        "r = wb.recover(**%r)\n"
        "h = wb.recover_heights(r.observations, %d, %r)\n"
        "np.savez(%r, recover=r.estimate.heights_um(), recover_heights=h.heights_um())\n"
        % (SMALL, SMALL["size"], SMALL["texel_um"], str(saved)))
    env = dict(ONE_THREAD, PYTHONPATH=os.path.join(conftest.BUILD, "python"))
    subprocess.run([sys.executable, "-c", script], check=True, env=env)
    py = np.load(saved)
    np.testing.assert_array_equal(py["recover_heights"], py["recover"])
    np.testing.assert_array_equal(py["recover"], np.load(cli_run / "estimate_height.npy"))


def test_recovers_from_the_cli_saved_observations(cli_run):
    truth = wb.Heightfield.from_exr(str(cli_run / "truth.exr"), 2.0)
    r = wb.recover(observations=str(cli_run / "observations.json"), size=8, texel_um=2.0, height_range_um=0.1)
    assert r.truth is None and r.notes == [] and r.warnings == []
    assert len(r.observations) == json.load(open(cli_run / "run.json"))["observations"]
    assert r.estimate.shape == (8, 8) and r.estimate.texel_um == 2.0
    assert wb.height_rel_rmse(r.estimate, truth) < 0.01
    assert rel_rmse(r.estimate.heights_um(), truth.heights_um()) < 0.01
    assert np.all(np.isnan(r.metrics["height_rel_rmse"]))  # no truth
    assert np.all(np.diff(r.metrics["seconds"]) >= 0)
    assert r.height_range_um == 0.1


def periodic_nearest_distances(positions, period):
    d = positions[None, :, :] - positions[:, None, :]
    d = (d + period / 2) % period - period / 2
    dist = np.hypot(d[..., 0], d[..., 1])
    np.fill_diagonal(dist, np.inf)
    return dist.min(axis=1)


@pytest.mark.parametrize("kw", [
    dict(rows=32, texel_um=2.0, height_range_um=2.0),
    dict(rows=32, texel_um=2.0, height_range_um=2.0, jitter=0.0),
    dict(rows=24, cols=40, texel_um=1.0, height_range_um=0.5, overlap=0.8, jitter=0.3, seed=7),
    dict(rows=16, texel_um=2.0, sigma_p_um=5.0, overlap=0.7, jitter=0.1, lambdas_um=[0.5, 0.55]),
    dict(rows=32, texel_um=2.0, height_range_um=2.0, overlap=0.8, position_uncertainty_um=6.0),
], ids=["defaults", "raster", "dense-rectangular", "given-wavelengths", "uncertain-positions"])
def test_plan_keeps_its_rules(kw):
    plan = wb.plan_acquisition(**kw)
    rows, cols, texel = kw["rows"], kw.get("cols", kw["rows"]), kw["texel_um"]
    # sigma_p: given, else 1.5 texels or the position uncertainty where that is wider.
    assert plan.sigma_p_um == kw.get("sigma_p_um", max(1.5 * texel, kw.get("position_uncertainty_um", 0.0)))
    period = np.array([rows * texel, cols * texel])
    support = 6.0 * plan.sigma_p_um
    pos = plan.positions_um
    assert pos.shape == (len(pos), 2) and len(pos) >= 4
    assert np.all(pos >= 0) and np.all(pos < period)
    # Every window overlaps its nearest neighbour (periodic) by at least the stated overlap,
    # which is at least the requested one; without jitter the worst case is met exactly.
    overlap_nn = 1.0 - periodic_nearest_distances(pos, period) / support
    assert plan.overlap >= kw.get("overlap", 0.6) - 1e-12
    assert overlap_nn.min() >= plan.overlap - 1e-12
    # Jittered about the raster centres by at most jitter x step (not a perfect raster).
    step = np.array(plan.step_um)
    offset = (pos / step) % 1.0 - 0.5
    jitter = kw.get("jitter", 0.2)
    assert np.abs(offset).max() <= jitter + 1e-9
    if jitter > 0:
        assert np.abs(offset).max() > 0.5 * jitter
    else:
        assert overlap_nn.min() == pytest.approx(plan.overlap, abs=1e-12)
    # Within 4x of Nyquist: du = 2 / (n lambda) <= 4 / (2 D) at the shortest wavelength (unless given).
    assert 2.0 / (plan.resolution * min(plan.lambdas_um)) <= 4.0 * 0.5 / support + 1e-12
    # Synthetic wavelengths of the pairs with lambda0 (planned) or all pairs (given).
    lam = plan.lambdas_um
    if "lambdas_um" in kw:
        assert lam == kw["lambdas_um"]
        expected = sorted((a * b / abs(a - b) for i, a in enumerate(lam) for b in lam[i + 1:]), reverse=True)
    else:
        expected = [lam[0] * b / abs(lam[0] - b) for b in lam[1:]]
        # the coarsest level unwraps the range: its ambiguity Lambda/2 covers the heights
        if expected:
            assert expected[0] / 2 >= kw["height_range_um"]
        else:
            assert kw["height_range_um"] < lam[0] / 4
    np.testing.assert_allclose(plan.synthetic_um, expected, rtol=1e-12)
    assert len(plan.notes) >= 3


def test_planned_and_simulated_observations():
    plan = wb.plan_acquisition(rows=8, texel_um=2.0, sigma_p_um=3.0, height_range_um=0.1, resolution=48)
    planned = wb.planned_observations(plan)
    assert len(planned) == len(plan.positions_um) * len(plan.lambdas_um)
    np.testing.assert_array_equal([(o.query.x_um, o.query.y_um) for o in planned], plan.positions_um)
    assert all(o.resolution == 48 and o.lambdas_um == [0.5] and not o.reference.any() for o in planned)
    truth = wb.with_height_range(wb.Heightfield.generate("isotropic", rows=8, texel_um=2.0, seed=5), 0.1)
    simulated = wb.simulate_observations(truth, plan)
    for o in simulated[:3]:
        np.testing.assert_array_equal(o.reference, o.render(truth).astype(np.float32))
    noisy = wb.simulate_observations(truth, plan, noise="poisson:1e4", seed=2)
    assert not np.array_equal(noisy[0].reference, simulated[0].reference)
    assert wb.check_acquisition(simulated, 8, 2.0, truth=truth) == []
    # Two footprints leave most texels unseen.
    sparse = wb.check_acquisition(simulated[:2], 8, 2.0)
    assert any("farther than 2 sigma_p" in w for w in sparse), sparse


def test_noise_has_the_stated_statistics():
    flat = np.ones((40, 50))
    # Poisson: counts k ~ Poisson(N R / sum R), returned as k sum R / N.
    n = 2e5
    noisy = wb.add_noise(flat, "poisson:%g" % n, seed=4)
    scale = flat.sum() / n  # 0.01: 100 photons per pixel
    counts = noisy / scale
    np.testing.assert_allclose(counts, np.round(counts), atol=1e-9)
    assert noisy.mean() == pytest.approx(1.0, abs=5 * np.sqrt(scale / flat.size))
    assert noisy.var() == pytest.approx(scale, rel=0.1)
    # Gaussian: R + REL max(R) z, clamped at 0.
    g = wb.add_noise(flat, "gaussian:0.05", seed=4)
    assert g.std() == pytest.approx(0.05, rel=0.1) and g.min() >= 0
    np.testing.assert_array_equal(wb.add_noise(flat, "gaussian:0.05", seed=4), g)
    assert not np.array_equal(wb.add_noise(flat, "gaussian:0.05", seed=5), g)
    np.testing.assert_array_equal(wb.add_noise(flat, "none"), flat)
    # Observations get new noisy references; the given ones are untouched.
    plan = wb.plan_acquisition(rows=8, texel_um=2.0, sigma_p_um=3.0, resolution=16)
    obs = wb.simulate_observations(wb.Heightfield.generate("isotropic", rows=8, texel_um=2.0), plan)
    before = obs[0].reference.copy()
    out = wb.add_noise(obs, "poisson:1e3", seed=1)
    np.testing.assert_array_equal(obs[0].reference, before)
    assert len(out) == len(obs) and not np.array_equal(out[0].reference, before)


def test_height_metrics():
    rng = np.random.default_rng(3)
    truth = wb.Heightfield(rng.normal(size=(6, 7)), texel_um=2.0, vscale=0.5)
    scaled = wb.with_height_range(truth, 0.3)
    h = scaled.heights_um()
    assert h.max() - h.min() == pytest.approx(0.3, rel=1e-12)
    assert h.mean() == pytest.approx(truth.heights_um().mean(), abs=1e-12)
    estimate = wb.Heightfield(truth.values + rng.normal(scale=0.1, size=(6, 7)) + 4.0, texel_um=2.0, vscale=0.5)
    assert wb.height_rel_rmse(estimate, truth) == pytest.approx(
        rel_rmse(estimate.heights_um(), truth.heights_um()), rel=1e-12)
    assert wb.height_rel_rmse(truth.with_values(truth.values + 1.0), truth) == pytest.approx(0.0, abs=1e-15)


@pytest.fixture(scope="module")
def small_observations():
    plan = wb.plan_acquisition(rows=8, texel_um=2.0, sigma_p_um=3.0, height_range_um=0.1, resolution=32)
    truth = wb.with_height_range(wb.Heightfield.generate("isotropic", rows=8, texel_um=2.0, seed=5), 0.1)
    return truth, wb.simulate_observations(truth, plan)


def test_recover_heights_reports_stages_and_stops(small_observations):
    truth, obs = small_observations
    seen = []

    def callback(m):
        seen.append(m)
        return m["stage"] != "blur:1"

    est = wb.recover_heights(obs, 8, 2.0, truth=truth, callback=callback,
                             settings=wb.RecoverSettings(blur_iterations=3))
    assert [m["stage"] for m in seen] == ["blur:0"] * 3 + ["blur:1"]
    assert [m["iteration"] for m in seen[:3]] == [1, 2, 3]
    assert all(np.isnan(m["height_rel_rmse"]) for m in seen)
    assert est.shape == (8, 8) and est.texel_um == 2.0

    class Stop(Exception):
        pass

    def raises(m):
        raise Stop()

    with pytest.raises(Stop):
        wb.recover_heights(obs, 8, 2.0, callback=raises)


def test_thesis_method_reduces_its_loss(small_observations):
    truth, obs = small_observations
    seen = []
    est = wb.recover_heights_thesis(obs, (8, 8), 2.0, truth=truth, epochs=30, callback=seen.append)
    assert [m["iteration"] for m in seen] == [10, 20, 30] and {m["stage"] for m in seen} == {"thesis"}
    assert seen[-1]["height_rel_rmse"] == pytest.approx(wb.height_rel_rmse(est, truth), rel=1e-12)
    r = wb.recover(**SMALL, method="thesis", resolution=32, settings=wb.RecoverSettings(epochs=20))
    assert r.loss == "cmsle:1" and r.method == "thesis" and list(r.metrics["iteration"]) == [10, 20]


def test_recover_callback_stops_early():
    r = wb.recover(**SMALL, resolution=32, callback=lambda m: m["iteration"] < 2)
    assert r.stopped and list(r.metrics["iteration"]) == [1, 2]
    assert r.estimate.shape == (8, 8) and r.truth.shape == (8, 8)
    assert len(r.notes) >= 3 and r.loss == "amplitude"
    r = wb.recover(**SMALL, resolution=32, noise="poisson:1e4", callback=lambda m: False)
    assert r.loss == "poisson:10000" and r.noise == "poisson:10000" and len(r.metrics["stage"]) == 1


def test_recover_refuses_what_cannot_fit_before_any_work():
    # size=1000 planned 492075 slices of 160x160 and grew until the machine ran out of memory
    # (the planner's Nyquist size then; its 48x48 now need ~16 GB, which a machine may have).
    with pytest.raises(MemoryError, match=r"needs about .* GB; the limit is 2 GB \(max-memory-gb\)"):
        wb.recover(size=1000, max_memory_gb=2)
    if os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE") < 200e9:  # the default limit
        with pytest.raises(MemoryError, match=r"the limit is .* \(physical memory\)"):
            wb.recover(size=1000, resolution=160)
    with pytest.raises(ValueError, match="max_memory_gb"):
        wb.recover(size=8, max_memory_gb=-1)


@pytest.mark.parametrize("call,needles", [
    (lambda: wb.recover(method="adam"), ["method", "adam"]),
    (lambda: wb.recover(noise="loud"), ["noise", "loud"]),
    (lambda: wb.recover(loss="cmsle:0"), ["cmsle:0"]),
    (lambda: wb.recover(size=0), ["size"]),
    (lambda: wb.recover(size=8, settings=wb.RecoverSettings(overlap=0.3)), ["overlap", "0.3"]),
    (lambda: wb.recover(size=8, settings=wb.RecoverSettings(overlap=0)), ["overlap", "0"]),
    (lambda: wb.recover(size=8, settings=wb.RecoverSettings(jitter=0.9)), ["jitter", "0.9"]),
    (lambda: wb.recover(lambdas_um=[0.5, -1]), ["lambdas_um"]),
    (lambda: wb.recover(height_range_um=0), ["height_range_um"]),
    (lambda: wb.recover(texel_um=-1), ["texel_um"]),
    (lambda: wb.recover(light=(0.9, 0.9)), ["light"]),
    (lambda: wb.recover(model="XYZ"), ["model", "XYZ"]),
    (lambda: wb.recover(settings=wb.RecoverSettings(field_iterations=-1)), ["field_iterations"]),
    (lambda: wb.recover(method="thesis", settings=wb.RecoverSettings(epochs=-1)), ["epochs"]),
    (lambda: wb.recover(method="thesis",
                        settings=wb.RecoverSettings(epochs=2**31 - 1)), ["epochs 2147483647", "0 to 10000000"]),
    (lambda: wb.recover(
                        settings=wb.RecoverSettings(field_iterations=10**8)), ["field_iterations 100000000", "0 to 10000000"]),
    (lambda: wb.recover(resolution=-2), ["resolution"]),
    (lambda: wb.recover(callback=3), ["callback"]),
    (lambda: wb.recover(truth=np.zeros((4, 4)), observations="o.json"), ["truth", "observations"]),
    (lambda: wb.recover(observations="o.json", noise="poisson:1e4"), ["noise"]),
    (lambda: wb.plan_acquisition(rows=0), ["rows"]),
    (lambda: wb.plan_acquisition(lambda_um=0.8), ["lambda_um", "0.8"]),
    (lambda: wb.plan_acquisition(max_step_ratio=1.0), ["max_step_ratio"]),
    (lambda: wb.plan_acquisition(height_range_um=-1.0), ["height_range_um"]),
    (lambda: wb.plan_acquisition(sigma_p_um=-1.0), ["sigma_p_um"]),
    (lambda: wb.plan_acquisition(position_uncertainty_um=float("nan")), ["position_uncertainty_um"]),
    (lambda: wb.recover(size=8, position_uncertainty_um=-1), ["position_uncertainty_um", "-1"]),
    (lambda: wb.plan_acquisition(height_range_um=1.0, lambda_min_um=0.49, lambda_max_um=0.51), ["0.125 um"]),
    (lambda: wb.add_noise(np.ones(4), "poisson:-3"), ["poisson:-3"]),
    (lambda: wb.add_noise(-np.ones(4), "poisson:3"), ["values", "negative"]),
    (lambda: wb.recover_heights([], 8, 2.0), ["observations"]),
    (lambda: wb.with_height_range(wb.Heightfield(np.zeros((3, 3))), 1.0), ["flat"]),
    (lambda: wb.with_height_range(wb.Heightfield(np.eye(3)), 0.0), ["range_um"]),
], ids=lambda v: "" if callable(v) else "-".join(v))
def test_bad_arguments_name_themselves(call, needles):
    with pytest.raises(ValueError) as info:
        call()
    message = str(info.value)
    assert "\n" not in message
    for needle in needles:
        assert needle in message, message


def test_bad_arguments_of_the_parts(small_observations):
    truth, obs = small_observations
    for kwargs, needle in [(dict(settings=wb.RecoverSettings(refine=2)), "refine"),
                           (dict(settings=wb.RecoverSettings(blur_widths=[4.0, 0.0])), "blur_widths"),
                           (dict(settings=wb.RecoverSettings(refine_loss="loud")), "loud"),
                           (dict(settings=wb.RecoverSettings(blur_iterations=-1)), "blur_iterations"),
                           (dict(truth=truth.values), "truth")]:
        with pytest.raises(ValueError, match=needle):
            wb.recover_heights(obs, 8, 2.0, **kwargs)
    with pytest.raises(ValueError, match="size"):
        wb.check_acquisition(obs, 0, 2.0)
    with pytest.raises(ValueError, match="report_every"):
        wb.recover_heights_thesis(obs, 8, 2.0, report_every=0)
    with pytest.raises(ValueError, match="lr"):
        wb.recover_heights_thesis(obs, 8, 2.0, lr=-1.0)
    with pytest.raises(RuntimeError, match="missing.json"):
        wb.recover(observations="missing.json")


def test_recover_flat_truth_reports_undefined_metric():
    # A flat truth has no relative height error: the recovery runs, with NaN metrics and a
    # warning (it used to raise from the metric after the work); a model without a field stage
    # (Kirchhoff; GHS and RGHS go through the separable proxy) is refused before the
    # observations are simulated.
    flat = wb.Heightfield(np.full((8, 8), 0.25), texel_um=2.0)
    r = wb.recover(flat, sigma_p_um=3.0, resolution=32,
                   settings=wb.RecoverSettings(field_iterations=3, refine_iterations=2))
    assert r.estimate.shape == (8, 8)
    assert np.all(np.isnan(r.metrics["height_rel_rmse"]))
    assert any("undefined: the truth is flat" in w for w in r.warnings)
    with pytest.raises(ValueError, match="Kirchhoff"):
        wb.recover(**SMALL, model="Kirchhoff")


def test_recover_takes_white_light_rgb_slices_alone():
    # White light (docs/recovery.md): every planned slice RGB of 4 wavelengths, no laser; the
    # blurred fit and the refinement run, no field stage; the estimate improves on flat.
    r = wb.recover(**SMALL, resolution=24, spectral=4, settings=wb.RecoverSettings(refine_iterations=10))
    stages = set(r.metrics["stage"])
    assert "refine" in stages and "unwrap" not in stages
    truth_um = r.truth.heights_um()
    flat = rel_rmse(np.zeros_like(truth_um), truth_um)
    assert rel_rmse(r.estimate.heights_um(), truth_um) < 0.5 * flat
    with pytest.raises(ValueError, match="spectral"):
        wb.recover(size=8, spectral=1)


# The field stage on tiles (docs/scale.md): recover()'s field_tile_threshold / field_tile_core are
# the CLI's --field-tile-threshold / --field-tile-core (the same estimate as the CLI's tiled run),
# recover_heights() takes them too (its field stage then reports every tile's iterations), and bad
# values name themselves. The smallest surface that cuts: 32 rows (3 cores of ~11 texels plus
# margins of 10), 8 columns (not cut).
TILED = dict(size=(32, 8), seed=3, lambdas_um=[0.6], height_range_um=0.2, resolution=24)
TILED_SETTINGS = dict(field_iterations=6, refine_iterations=3)
TILED_CLI = ["--size", "32x8", "--seed", "3", "--lambdas-um", "0.6", "--height-range-um", "0.2", "--resolution", "24",
             "--field-iterations", "6", "--refine-iterations", "3"]


def test_field_tile_knobs_are_the_clis(tmp_path):
    cli = os.path.join(conftest.BUILD, "bin", "wavebrdf")
    out = tmp_path / "cli"
    subprocess.run([cli, "recover", *TILED_CLI, "--field-tile-threshold", "16", "--field-tile-core", "12",
                    "--no-plots", "--quiet", "--out", str(out)], check=True, env=ONE_THREAD)
    cli_um = np.load(out / "estimate_height.npy")
    r = wb.recover(**TILED, settings=wb.RecoverSettings(**TILED_SETTINGS, field_tile_threshold=16, field_tile_core=12))
    # Three tiles of 6 iterations each (the whole surface: 6 rows).
    assert list(r.metrics["stage"]).count("field:0.6") == 18
    np.testing.assert_allclose(r.estimate.heights_um(), cli_um, rtol=0, atol=1e-6 * np.abs(cli_um).max())
    whole = wb.recover(**TILED, settings=wb.RecoverSettings(**TILED_SETTINGS, field_tile_threshold=0))
    assert list(whole.metrics["stage"]).count("field:0.6") == 6
    assert np.abs(whole.estimate.heights_um() - cli_um).max() > 1e-5 * np.abs(cli_um).max(), "tiles changed nothing"

    stages = []
    callback = lambda m: stages.append(m["stage"]) or True
    wb.recover_heights(r.observations, (32, 8), 2.0, callback=callback,
                       settings=wb.RecoverSettings(blur_iterations=1, field_iterations=2, refine_iterations=0,
                                                   field_tile_threshold=16, field_tile_core=12))
    assert stages.count("field:0.6") == 6
    stages.clear()
    wb.recover_heights(r.observations, (32, 8), 2.0, callback=callback,
                       settings=wb.RecoverSettings(blur_iterations=1, field_iterations=2, refine_iterations=0,
                                                   field_tile_threshold=0))
    assert stages.count("field:0.6") == 2

    for call, needle in [(lambda: wb.recover(size=8,
                                             settings=wb.RecoverSettings(field_tile_core=4)), "field_tile_core"),
                         (lambda: wb.recover(size=8,
                                             settings=wb.RecoverSettings(field_tile_threshold=-3)), "field_tile_threshold"),
                         (lambda: wb.recover_heights(r.observations, (32, 8), 2.0,
                                                     settings=wb.RecoverSettings(field_tile_core=5000)),
                          "field_tile_core"),
                         (lambda: wb.recover_heights(r.observations, (32, 8), 2.0,
                                                     settings=wb.RecoverSettings(field_tile_threshold=-1)),
                          "field_tile_threshold")]:
        with pytest.raises(ValueError, match=needle):
            call()


def test_steep_surfaces_are_observed_under_oblique_lights():
    # ±4 µm at correlation 4 texels (expected rms slope 0.33): the planner adds 4 oblique lights,
    # every position observed under each; oblique_lights=False keeps the one light, and then
    # the check names the texels whose light leaves every slice.
    kw = dict(size=8, resolution=16, height_range_um=8.0, seed=6301, quiet=True)
    fast = dict(field_iterations=1, refine_iterations=1)
    many = wb.recover(**kw, settings=wb.RecoverSettings(**fast))
    one = wb.recover(**kw, settings=wb.RecoverSettings(**fast, oblique_lights=False))
    assert len(many.observations) == 5 * len(one.observations)
    lights = {tuple(o.query.light) for o in many.observations}
    assert len(lights) == 5 and (0.0, 0.0) in lights
    assert all(abs(math.hypot(*w) - 0.8) < 1e-12 for w in lights - {(0.0, 0.0)})
    assert any("oblique lights" in n for n in many.notes)
    assert wb.plan_acquisition(height_range_um=8.0).oblique_lights == []  # the planner alone: one light

    def unseen(result, phrase):
        found = [w for w in result.warnings if phrase in w]
        return int(found[0].split()[0]) if found else 0

    assert unseen(one, "reflect the light beyond the slice's rim") > 0
    assert unseen(many, "reflect each of the 5 lights beyond") < unseen(one, "reflect the light beyond")


def test_recover_settings_group_the_rare_keywords():
    # The settings object and its old keywords run the same recovery; the old ones warn.
    s = wb.RecoverSettings(epochs=4, jitter=0.1)
    assert s.epochs == 4 and s.jitter == 0.1 and s.field_iterations is None
    assert repr(s) == "RecoverSettings(epochs=4, jitter=0.1)"
    s.field_iterations = 3
    assert s.field_iterations == 3
    new = wb.recover(size=8, resolution=16, method="thesis", quiet=True, settings=wb.RecoverSettings(epochs=4))
    with pytest.warns(FutureWarning, match=r"recover\(epochs=...\) is deprecated"):
        old = wb.recover(size=8, resolution=16, method="thesis", quiet=True, epochs=4)
    np.testing.assert_array_equal(new.estimate.values, old.estimate.values)
    assert list(new.metrics["iteration"]) == list(old.metrics["iteration"])
    with pytest.raises(TypeError, match="unexpected keyword argument 'epoch'"):
        wb.recover(size=8, epoch=4)
    with pytest.raises(ValueError, match="settings = 3 is invalid; expected a RecoverSettings"):
        wb.recover(size=8, settings=3)
    # Values are checked once, by the library, named as Python spells them.
    for settings, needle in [(wb.RecoverSettings(field_tile_core=4), "field_tile_core 4 texels is invalid"),
                             (wb.RecoverSettings(refine_coarse_iterations=10**8), "refine_coarse_iterations"),
                             (wb.RecoverSettings(simulate_sigma_factor=9.0), "simulate_sigma_factor 9 is invalid"),
                             (wb.RecoverSettings(epochs="many"), "epochs = 'many' is invalid")]:
        with pytest.raises(ValueError, match=needle):
            wb.recover(size=8, settings=settings)


def test_plan_only_plans_as_the_cli_and_stops(cli, tmp_path):
    """recover(plan_only=True) plans as `wavebrdf recover --plan-only` does, the photon plan's pilot
    included (16² of 20 nm at 1e5 photons: 3 exposures, a pilot of 4 draws), and recovers nothing."""
    args = dict(size=16, resolution=48, noise="poisson:1e5", height_range_um=0.02, seed=4)
    subprocess.run([cli, "recover", "--size", "16", "--resolution", "48", "--noise", "poisson:1e5",
                    "--height-range-um", "0.02", "--seed", "4", "--no-plots", "--threads", "1", "--quiet",
                    "--plan-only", "--out", str(tmp_path / "plan")], check=True)
    with open(tmp_path / "plan" / "run.json", encoding="utf-8") as f:
        want = json.load(f)
    r = wb.recover(**args, plan_only=True, quiet=True)
    assert r.estimate is None and r.metrics == {}
    got = r.plan
    assert got["plan_only"] is True
    for key in ("plan", "noise", "loss", "observations", "wavelengths_um", "sigma_p_um", "positions_um"):
        assert got[key] == want[key], key
    assert got["photon_plan"]["exposures"] == want["photon_plan"]["exposures"] == 3
    assert got["photon_plan"]["pilot"]["ran"]
    for key in ("errors_um", "ratio", "upper_ratio", "exposures"):
        assert got["photon_plan"]["pilot"][key] == want["photon_plan"]["pilot"][key], key
    assert len(r.observations) == len(got["positions_um"]) == got["observations"]
    assert r.noise == "poisson:300000"
    with pytest.raises(ValueError, match="plan_only"):
        wb.recover(observations=r.observations, plan_only=True, quiet=True)
