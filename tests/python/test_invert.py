"""invert(): the same run as `wavebrdf invert` for the same options, callbacks, the other
modes, and errors."""
import csv
import subprocess

import numpy as np
import pytest

import wavebrdf as wb

COLUMNS = ["loss", "brdf_mse", "cmsle_1", "cmsle_0.001", "rgb_mse", "rgb_gamma_mse", "height_mse"]


def read_metrics(path):
    with open(path) as f:
        rows = list(csv.DictReader(f))
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}


@pytest.mark.parametrize("cli_args,py_args", [
    (["--epochs", 12, "--size", 12, "--seed", 4, "--init", "noisy:0.1", "--lr", 0.005, "--loss", "cmsle:0.01",
      "--spectral", 3, "--resolution", 16, "--sigma-p-um", 3, "--light-x", 0.1, "--texel-um", 0.8],
     dict(epochs=12, size=12, seed=4, init="noisy:0.1", lr=0.005, loss="cmsle:0.01", spectral=3, resolution=16,
          sigma_p_um=3.0, light=(0.1, 0.0), texel_um=0.8)),
    (["--epochs", 10, "--size", "10x12", "--positions", "random", "--lambda-um", 0.55, "--resolution", 12,
      "--model", "GHS", "--loss", "mse", "--decay", 0.01],
     dict(epochs=10, size=(10, 12), positions="random", lambda_um=0.55, resolution=12, model="GHS", loss="mse",
          decay=0.01)),
    (["--epochs", 6, "--size", 10, "--optimizer", "lbfgs", "--resolution", 12, "--x-um", 2.5, "--y-um", 7.0],
     dict(epochs=6, size=10, optimizer="lbfgs", resolution=12, x_um=2.5, y_um=7.0)),
], ids=["adam-noisy-spectral", "adam-random-positions", "lbfgs"])
def test_same_run_as_the_cli(tmp_path, cli, cli_args, py_args):
    out = tmp_path / "run"
    subprocess.run([cli, "invert", *map(str, cli_args), "--out", str(out), "--no-plots", "--quiet"], check=True)
    from_cli = read_metrics(out / "metrics.csv")
    result = wb.invert(**py_args)
    m = result.metrics
    np.testing.assert_array_equal(m["epoch"], from_cli["epoch"])
    for k in COLUMNS:
        np.testing.assert_allclose(m[k], from_cli[k], rtol=1e-8, err_msg=k)  # csv keeps 10 digits
    estimate = wb.Heightfield.from_exr(str(out / "estimate.exr"))  # float EXR
    np.testing.assert_allclose(result.estimate.values, estimate.values, rtol=0,
                               atol=1e-6 * np.abs(estimate.values).max())
    truth = wb.Heightfield.from_exr(str(out / "truth.exr"))
    np.testing.assert_allclose(result.truth.values, truth.values, rtol=0, atol=1e-6 * np.abs(truth.values).max())
    assert result.epochs == py_args["epochs"] and not result.stopped
    assert result.estimate.texel_um == py_args.get("texel_um", 1.0)


def test_default_run_reduces_the_loss():
    r = wb.invert(epochs=40)
    m = r.metrics
    assert len(m["epoch"]) == 41 and m["epoch"][-1] == 40
    assert m["loss"][-1] < 0.5 * m["loss"][0]
    assert r.estimate.shape == (16, 16) and r.truth.shape == (16, 16)
    assert len(r.observations) == 1 and r.observations[0].channels == 3
    assert r.final_slices[0].shape == (32, 32, 3)
    # final_slices are the estimate's slices.
    np.testing.assert_allclose(r.final_slices[0], r.observations[0].render(r.estimate), rtol=1e-12, atol=0)
    assert np.all(np.diff(m["seconds"]) >= 0)


def test_callback_sees_each_epoch_and_can_stop():
    seen = []

    def callback(metrics, estimate):
        seen.append((metrics["epoch"], metrics["loss"], estimate.copy()))
        return metrics["epoch"] < 3

    r = wb.invert(epochs=50, size=8, resolution=12, callback=callback)
    assert [s[0] for s in seen] == [0, 1, 2, 3]
    assert r.stopped and r.epochs == 3 and len(r.metrics["epoch"]) == 4
    assert np.all(seen[0][2] == 0.0)  # the flat start
    np.testing.assert_array_equal(seen[-1][2], r.estimate.values)
    assert seen[-1][1] == r.metrics["loss"][-1]

    class Stop(Exception):
        pass

    def raises(metrics, estimate):
        if metrics["epoch"] == 2:
            raise Stop("from the callback")

    with pytest.raises(Stop):
        wb.invert(epochs=10, size=8, resolution=12, callback=raises)


def test_truth_inputs_and_observations(tmp_path):
    truth = wb.Heightfield.generate("isotropic", rows=10, rms_height_um=0.3, correlation_um=2.0, seed=3)
    scaled = truth.with_scale(0.5, 2.0)
    a = wb.invert(truth=scaled, epochs=3, resolution=12)  # scale inherited from the Heightfield
    assert a.estimate.texel_um == 0.5 and a.estimate.vscale == 2.0
    b = wb.invert(truth=truth.values, texel_um=0.5, vscale=2.0, epochs=3, resolution=12)
    np.testing.assert_array_equal(a.metrics["loss"], b.metrics["loss"])
    path = str(tmp_path / "t.exr")
    truth.save_exr(path)
    c = wb.invert(truth=path, texel_um=0.5, vscale=2.0, epochs=3, resolution=12)
    np.testing.assert_allclose(c.metrics["loss"], a.metrics["loss"], rtol=1e-6)
    # Fitting given observations (no truth: height_mse is NaN), several positions.
    q1 = wb.Query(x_um=2.0, y_um=3.0, sigma_p_um=4.0, spectral=3)
    q2 = wb.Query(x_um=7.0, y_um=6.0, sigma_p_um=4.0, spectral=3)
    obs = [wb.Observation(q, wb.render(truth, q, 12)) for q in (q1, q2)]
    r = wb.invert(observations=obs, size=10, epochs=60)
    assert np.isnan(r.metrics["height_mse"]).all() and r.truth is None
    assert r.metrics["loss"][-1] < 0.7 * r.metrics["loss"][0]
    wb.write_observations(str(tmp_path / "o.json"), obs)
    r2 = wb.invert(observations=str(tmp_path / "o.json"), size=10, epochs=60)
    np.testing.assert_allclose(r2.metrics["loss"], r.metrics["loss"], rtol=1e-12)
    # Listed positions render one observation each.
    r3 = wb.invert(truth=truth, positions=[(1.0, 1.0), (5.0, 5.0), (8.0, 2.0)], epochs=1, resolution=8)
    assert [(o.query.x_um, o.query.y_um) for o in r3.observations] == [(1.0, 1.0), (5.0, 5.0), (8.0, 2.0)]
    (tmp_path / "p.json").write_text('{"positions": [[1.0, 1.0], [5.0, 5.0], [8.0, 2.0]]}')
    r4 = wb.invert(truth=truth, positions=str(tmp_path / "p.json"), epochs=1, resolution=8)
    np.testing.assert_array_equal(r4.metrics["loss"], r3.metrics["loss"])


@pytest.mark.parametrize("kwargs,message", [
    (dict(truth=np.zeros((4, 4)), observations=[]), "exclude each other"),
    (dict(optimizer="sgd"), "optimizer"),
    (dict(optimizer="lbfgs", positions="random"), "random"),
    (dict(epochs=-1), "epochs"),
    (dict(epochs=2**31 - 1), "epochs 2147483647 is out of range; expected 0 to 10000000"),
    (dict(x_um=float("nan")), "x_um"),
    (dict(sigma_p_um=1000.0), "160 um"),  # the default truth: 16 x 16 texels of 1 um
    (dict(lr=0.0), "lr"),
    (dict(size=0), "size"),
    (dict(size="big"), "size"),
    (dict(init="noisy:x"), "init"),
    (dict(init=np.zeros((3, 3))), "init is 3x3"),
    (dict(observations=[], init="noisy:0.1"), "observations is empty"),
    (dict(positions=[(1.0,)]), "positions"),
    (dict(positions="sometimes"), "positions"),
    (dict(loss="l1"), "loss"),
    (dict(light=(2.0, 0.0)), "light"),
    (dict(sigma_p_um=0.0), "sigma_p_um"),
    (dict(spectral=0), "spectral"),
    (dict(callback=3), "callback"),
    (dict(truth=np.zeros((4, 4)), texel_um=-1.0), "texel_um"),
])
def test_errors(kwargs, message):
    kwargs.setdefault("epochs", 1)
    with pytest.raises((ValueError, RuntimeError)) as e:
        wb.invert(**kwargs)
    assert message in str(e.value)


def test_invert_refuses_what_cannot_fit_before_any_work():
    # The CLI's --max-memory-gb: the estimate is checked before the references are rendered.
    with pytest.raises(MemoryError, match=r"invert \(16x16 heights, 1 observation\(s\) of 32x32\) needs about .*"
                                          r"\(max-memory-gb\); raise it with max_memory_gb="):
        wb.invert(epochs=1, max_memory_gb=1e-6)
    with pytest.raises(ValueError, match="max_memory_gb"):
        wb.invert(epochs=1, max_memory_gb=-1)
    assert wb.invert(epochs=1, size=8, resolution=8, max_memory_gb=100).epochs == 1
