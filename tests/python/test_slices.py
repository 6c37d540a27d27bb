"""Fitting one's own slice from Python: per-pixel weights of an Observation (a masked pixel
changes neither the loss nor its gradient), files that keep them; calls that miss or misspell a
keyword are told which; height_rel_rmse takes arrays."""
import subprocess

import numpy as np
import pytest

import wavebrdf as wb


def _truth(seed=1, n=8):
    rng = np.random.default_rng(seed)
    return wb.Heightfield(0.3 * rng.standard_normal((n, n)), texel_um=1.0)


def _observation(weights=None, reference=None):
    truth = _truth()
    q = wb.Query(x_um=4.0, y_um=4.0, sigma_p_um=2.0, lambda_um=0.55, light=(0.1, 0.0))
    n = 12
    ref = wb.render_slice(truth, resolution=n, x_um=4.0, y_um=4.0, sigma_p_um=2.0, lambda_um=0.55,
                          light=(0.1, 0.0))[..., 0] if reference is None else reference
    return q, ref, wb.Observation(q, ref, weights=weights)


def _mask(n=12, seed=3):
    rng = np.random.default_rng(seed)
    m = (rng.random((n, n)) > 0.3).astype(np.float64)
    m[0, 0] = 1.0
    m[0, 1] = 0.0
    return m


def test_weighted_loss_is_the_mean_over_the_unmasked_pixels():
    mask = _mask()
    q, ref, obs = _observation(weights=mask)
    start = _truth(seed=2)
    value, grad = wb.observation_loss(start, [obs], "mse")
    estimate = obs.render(start)
    # Independent: the MSE of the unmasked pixels alone, in NumPy.
    r = np.asarray(ref, dtype=np.float32).astype(np.float64)
    expected = np.mean(((estimate - r) ** 2)[mask > 0])
    assert value == pytest.approx(expected, rel=1e-12)
    # Finite differences of the weighted loss on a few heights.
    h = 1e-5
    for k in [(0, 0), (3, 5), (7, 2)]:
        up, down = start.values.copy(), start.values.copy()
        up[k] += h
        down[k] -= h
        fd = (wb.observation_loss(wb.Heightfield(up), [obs], "mse")[0]
              - wb.observation_loss(wb.Heightfield(down), [obs], "mse")[0]) / (2 * h)
        assert grad[k] == pytest.approx(fd, rel=1e-6, abs=1e-9)


def test_masked_pixels_may_hold_anything():
    mask = _mask()
    q, ref, obs = _observation(weights=mask)
    spoilt = np.array(ref, dtype=np.float64)
    spoilt[mask == 0] = np.nan
    spoilt[0, 1] = np.inf
    other = wb.Observation(q, spoilt, weights=mask)
    start = _truth(seed=2)
    a = wb.observation_loss(start, [obs], "cmsle:0.1")
    b = wb.observation_loss(start, [other], "cmsle:0.1")
    assert a[0] == b[0]
    assert np.array_equal(a[1], b[1])
    assert other.weights.shape == (12, 12)
    assert other.weights.dtype == np.float32
    assert obs.weights is not None and _observation()[2].weights is None
    with pytest.raises(ValueError, match="not finite"):
        wb.Observation(q, spoilt)  # without weights every value counts


def test_bad_weights_are_named():
    q, ref, _ = _observation()
    with pytest.raises(ValueError, match=r"weights has shape \(3, 3\); expected \(12, 12\)"):
        wb.Observation(q, ref, weights=np.ones((3, 3)))
    w = np.ones((12, 12))
    w[2, 3] = -1.0
    with pytest.raises(ValueError, match=r"weight of pixel \(2, 3\) is -1"):
        wb.Observation(q, ref, weights=w)
    with pytest.raises(ValueError, match="every weight is 0"):
        wb.Observation(q, ref, weights=np.zeros((12, 12)))


@pytest.mark.parametrize("name", ["set.json", "set.h5"])
def test_weights_survive_a_file(tmp_path, name):
    if name.endswith(".h5") and not wb.built_with_hdf5():
        pytest.skip("built without HDF5")
    mask = _mask()
    mask[4, 4] = 0.25
    _, _, obs = _observation(weights=mask)
    wb.write_observations(str(tmp_path / name), [obs])
    back = wb.read_observations(str(tmp_path / name))
    assert np.array_equal(back[0].weights, mask.astype(np.float32))


def test_missing_keyword_is_named():
    h = np.zeros((8, 8))
    with pytest.raises(TypeError, match=r"render_slice\(\) missing required keyword argument 'resolution'"):
        wb.render_slice(h)
    with pytest.raises(TypeError, match=r"unexpected keyword argument 'resoluton'; did you mean 'resolution'\?"):
        wb.render_slice(h, resoluton=8)
    with pytest.raises(TypeError, match=r"slice_gradient\(\) missing required argument 'weights'"):
        wb.slice_gradient(h, resolution=8)
    # A value of the wrong type is still pybind11's own message.
    with pytest.raises(TypeError, match="incompatible function arguments"):
        wb.render_slice(h, resolution="eight")
    # The functions still work and keep their documentation.
    assert wb.render_slice(h, resolution=4, sigma_p_um=2.0).shape == (4, 4, 3)
    assert "resolution" in wb.render_slice.__doc__


def test_height_rel_rmse_takes_arrays():
    rng = np.random.default_rng(5)
    t = rng.standard_normal((6, 7))
    e = t + 0.1 * rng.standard_normal((6, 7))
    d = (e - e.mean()) - (t - t.mean())
    expected = np.sqrt(np.mean(d ** 2)) / (t.max() - t.min())
    assert wb.height_rel_rmse(e, t) == pytest.approx(expected, rel=1e-12)
    # An array beside a Heightfield is in the Heightfield's units.
    hf = wb.Heightfield(t, texel_um=0.5, vscale=3.0)
    assert wb.height_rel_rmse(e, hf) == pytest.approx(expected, rel=1e-12)
    assert wb.height_rel_rmse(wb.Heightfield(e, texel_um=0.5, vscale=3.0), hf) == pytest.approx(expected, rel=1e-12)
    assert np.isfinite(wb.height_rel_rmse_plane_removed(e, t))
    with pytest.raises(ValueError, match="estimate has shape"):
        wb.height_rel_rmse(np.zeros((2, 2, 2)), t)


def test_observation_from_a_slice_file_takes_its_query(tmp_path, cli):
    truth = _truth()
    path = str(tmp_path / "s.exr")
    # render --out writes the query into the slice's attributes.
    hf_path = str(tmp_path / "h.exr")
    truth.save_exr(hf_path)
    subprocess.run([cli, "render", "--heightfield", hf_path, "--resolution", "12", "--x-um", "3", "--y-um", "5",
                    "--sigma-p-um", "2", "--light-x", "0.2", "--light-y", "-0.1", "--lambda-um", "0.6",
                    "--out", path, "--quiet"], check=True)
    mask = _mask()
    obs = wb.Observation.from_slice(path, weights=mask)
    assert obs.lambdas_um == [0.6]
    assert obs.query.sigma_p_um == 2.0 and obs.query.x_um == 3.0 and tuple(obs.query.light) == (0.2, -0.1)
    assert np.array_equal(obs.weights, mask.astype(np.float32))
    # From the true heights the loss is 0 up to the slice's float rounding: the query is the right one.
    assert wb.observation_loss(truth, [obs], "cmsle:1")[0] < 1e-12
    np.save(str(tmp_path / "plain.npy"), np.zeros((4, 4)))
    with pytest.raises((ValueError, RuntimeError)):
        wb.Observation.from_slice(str(tmp_path / "plain.npy"))
