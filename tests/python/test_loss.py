"""Losses and metrics against their formulas written here in NumPy; gradients by finite
differences; errors."""
import numpy as np
import pytest

import wavebrdf as wb


def formulas(e, r, channels_last):
    pixels = e.size // (e.shape[-1] if channels_last else 1)
    return {
        "mse": np.sum((e - r) ** 2) / pixels,
        "cmsle:1": np.sum((np.log(e + 1) - np.log(r + 1)) ** 2) / pixels,
        "cmsle:0.01": np.sum((np.log(e + 0.01) - np.log(r + 0.01)) ** 2) / pixels,
        "amplitude": np.sum((np.sqrt(e + 1e-30) - np.sqrt(r)) ** 2) / pixels,
    }


@pytest.mark.parametrize("shape", [(6, 6, 3), (6, 6), (5,)])
def test_values_and_gradients(rng, shape):
    e = rng.uniform(0.1, 3.0, shape)
    r = rng.uniform(0.1, 3.0, shape)
    expected = formulas(e, r, len(shape) == 3)
    for spec, value in expected.items():
        loss = wb.Loss(spec)
        assert loss(e, r) == pytest.approx(value, rel=1e-12)
        v, g = loss.value_and_gradient(e, r)
        assert v == pytest.approx(value, rel=1e-12)
        assert g.shape == e.shape and g.dtype == np.float64
        # Central differences of the loss in every entry.
        h = 1e-6
        fd = np.zeros_like(e)
        for k in np.ndindex(e.shape):
            d = np.zeros_like(e)
            d[k] = h
            fd[k] = (loss(e + d, r) - loss(e - d, r)) / (2 * h)
        np.testing.assert_allclose(g, fd, rtol=1e-6, atol=1e-9)
    assert wb.mse(e, r) == pytest.approx(expected["mse"], rel=1e-12)
    assert wb.cmsle(e, r) == pytest.approx(expected["cmsle:1"], rel=1e-12)
    assert wb.cmsle(e, r, epsilon=0.01) == pytest.approx(expected["cmsle:0.01"], rel=1e-12)
    assert wb.amplitude(e, r) == pytest.approx(expected["amplitude"], rel=1e-12)
    # float32 input
    assert wb.mse(e.astype(np.float32), r.astype(np.float32)) == pytest.approx(expected["mse"], rel=1e-5)


def test_poisson_deviance(rng):
    e = rng.uniform(0.1, 3.0, (4, 4, 3))
    r = rng.uniform(0.1, 3.0, (4, 4, 3))
    loss = wb.Loss("poisson:1000")
    assert loss.kind == "poisson" and loss.photons == 1000
    s = 1000 / r.sum()
    k, mu = s * r + 1e-9, s * e + 1e-9
    assert loss(e, r) == pytest.approx(np.sum(2 * (k * np.log(k / mu) - (k - mu))) / 16, rel=1e-9)


def test_loss_objects():
    assert wb.Loss().kind == "cmsle" and wb.Loss().epsilon == 1.0
    assert str(wb.Loss("cmsle:0.01")) == "cmsle:0.01"
    assert repr(wb.Loss("mse")) == "Loss('mse')"
    for bad in ("l2", "cmsle:", "cmsle:-1", "cmsle:nan", "MSE"):
        with pytest.raises(ValueError):
            wb.Loss(bad)
    with pytest.raises(ValueError, match="epsilon"):
        wb.cmsle(np.ones(3), np.ones(3), epsilon=0.0)


@pytest.mark.parametrize("e,r,message", [
    (np.ones((4, 4, 3)), np.ones((4, 4)), "reference has shape (4, 4)"),
    (np.ones((4,), dtype=np.int64), np.ones(4), "estimate has dtype int64"),
    (np.array([1.0, np.nan]), np.ones(2), "estimate[1]"),
    (np.ones(2), np.array([np.inf, 1.0]), "reference[0]"),
    (np.ones(0), np.ones(0), "estimate is empty"),
])
def test_errors(e, r, message):
    for f in (wb.mse, wb.Loss("cmsle:1"), wb.Loss("amplitude").value_and_gradient, wb.rgb_mse):
        with pytest.raises(ValueError) as err:
            f(e, r)
        assert message in str(err.value)


def test_metrics(rng):
    e = rng.uniform(0.0, 5.0, (5, 5, 3))
    r = rng.uniform(0.0, 5.0, (5, 5, 3))
    t = lambda x: x / (1 + x)  # noqa: E731  Reinhard
    assert wb.rgb_mse(e, r) == pytest.approx(np.mean((t(e) - t(r)) ** 2), rel=1e-12)
    assert wb.rgb_gamma_mse(e, r) == pytest.approx(np.mean((t(e) ** (1 / 2.2) - t(r) ** (1 / 2.2)) ** 2), rel=1e-12)
    # Grey slices are treated as RGB with equal channels.
    assert wb.rgb_mse(e[..., 0], r[..., 0]) == pytest.approx(np.mean((t(e[..., 0]) - t(r[..., 0])) ** 2), rel=1e-12)
    with pytest.raises(ValueError):
        wb.rgb_mse(np.ones((2, 2, 2)), np.ones((2, 2, 2)))
    a = rng.normal(size=(6, 6))
    b = rng.normal(size=(6, 6))
    assert wb.height_mse(a, b) == pytest.approx(np.mean(((a - a.mean()) - (b - b.mean())) ** 2), rel=1e-12)
    assert wb.height_mse(a, a + 5.0) == pytest.approx(0.0, abs=1e-20)
    with pytest.raises(ValueError, match="truth has shape"):
        wb.height_mse(a, b[:5])
