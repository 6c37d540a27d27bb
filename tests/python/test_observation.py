"""Observations and observation_loss: the library's loss gradient against finite differences and
against the composition Loss.value_and_gradient + gradient (our RGB/spectral mapping); JSON."""
import numpy as np
import pytest

import wavebrdf as wb


def make_case(rng, spectral):
    truth = wb.Heightfield(rng.normal(0, 0.4, (10, 10)), texel_um=0.9, vscale=1.1)
    estimate = wb.Heightfield(rng.normal(0, 0.4, (10, 10)), texel_um=0.9, vscale=1.1)
    queries = [wb.Query(x_um=4.0, y_um=5.0, sigma_p_um=1.8, spectral=spectral),
               wb.Query(x_um=1.0, y_um=8.0, sigma_p_um=2.2, light=(0.2, 0.0), model="GHS", spectral=spectral)]
    observations = []
    for q in queries:
        ref = wb.render(truth, q, 12)
        observations.append(wb.Observation(q, ref if spectral else ref[..., 0]))
    return truth, estimate, queries, observations


@pytest.mark.parametrize("spectral", [None, 4], ids=["mono", "spectral"])
@pytest.mark.parametrize("spec", ["cmsle:1", "mse", "amplitude"])
def test_loss_gradient_two_ways(rng, spectral, spec):
    truth, estimate, queries, observations = make_case(rng, spectral)
    value, grad = wb.observation_loss(estimate, observations, spec)
    assert grad.shape == (10, 10) and grad.dtype == np.float64
    # The same loss through the Python pieces: render, Loss.value_and_gradient, gradient (VJP).
    loss = wb.Loss(spec)
    total, total_grad = 0.0, np.zeros((10, 10))
    for q, o in zip(queries, observations):
        s = wb.render(estimate, q, 12)
        if spectral:
            v, d = loss.value_and_gradient(s, o.reference)
        else:  # one wavelength: a single channel, whose weights go into R (G, B add nothing)
            v, d1 = loss.value_and_gradient(s[..., 0], o.reference)
            d = np.zeros_like(s)
            d[..., 0] = d1
        total += v / 2
        total_grad += wb.gradient(estimate, q, d) / 2
    assert value == pytest.approx(total, rel=1e-12)
    np.testing.assert_allclose(grad, total_grad, rtol=0, atol=1e-10 * np.abs(grad).max())
    # Finite differences along a random direction.
    direction = rng.normal(size=(10, 10))
    f = lambda t: wb.observation_loss(estimate.with_values(estimate.values + t * direction),  # noqa: E731
                                      observations, spec)[0]
    fd1, fd2 = (f(1e-5) - f(-1e-5)) / 2e-5, (f(5e-6) - f(-5e-6)) / 1e-5
    # (The amplitude loss has sqrt's curvature near I = 0, where spectral RGB can reach.)
    assert np.sum(grad * direction) == pytest.approx((4 * fd2 - fd1) / 3, rel=1e-4 if spec == "amplitude" else 1e-6)
    # At the truth the loss vanishes (up to the references' rounding to float32).
    assert wb.observation_loss(truth, observations, spec)[0] == pytest.approx(0.0, abs=1e-13)


def test_observation_object(rng):
    truth, _, queries, observations = make_case(rng, 3)
    o = observations[0]
    assert o.resolution == 12 and o.channels == 3 and len(o.lambdas_um) == 3
    assert o.reference.shape == (12, 12, 3) and not o.reference.flags.writeable
    assert o.reference.dtype == np.float32  # stored in float
    np.testing.assert_array_equal(o.render(truth).astype(np.float32), o.reference)
    q = o.query
    assert (q.x_um, q.y_um, q.sigma_p_um, q.model) == (4.0, 5.0, 1.8, "OHS")
    mono = wb.Observation(wb.Query(lambda_um=0.6), np.zeros((8, 8)))
    assert mono.channels == 1 and mono.reference.shape == (8, 8)


@pytest.mark.parametrize("query,reference,message", [
    (wb.Query(), np.zeros((8, 8, 3)), "expected (n, n) for a single-wavelength query"),
    (wb.Query(spectral=4), np.zeros((8, 8)), "expected (n, n, 3) for a spectral query"),
    (wb.Query(), np.zeros((8, 9)), "reference has shape (8, 9)"),
    (wb.Query(), np.full((4, 4), np.nan), "reference[0, 0]"),
])
def test_observation_errors(query, reference, message):
    with pytest.raises(ValueError) as e:
        wb.Observation(query, reference)
    assert message in str(e.value)


def test_observation_loss_errors(rng):
    truth, estimate, _, observations = make_case(rng, None)
    with pytest.raises(ValueError, match="observations is empty"):
        wb.observation_loss(estimate, [], "mse")
    with pytest.raises(ValueError, match="observations"):
        wb.observation_loss(estimate, [1, 2], "mse")
    with pytest.raises(ValueError):
        wb.observation_loss(estimate, observations, "l1")
    assert wb.observation_loss(estimate, observations[0], wb.Loss("mse"))[0] > 0


def test_json_round_trip(tmp_path, rng):
    truth, estimate, _, observations = make_case(rng, 3)
    path = str(tmp_path / "obs.json")
    wb.write_observations(path, observations)
    back = wb.read_observations(path)
    assert len(back) == 2
    for a, b in zip(observations, back):
        np.testing.assert_array_equal(a.reference, b.reference)
        assert (a.query.x_um, a.query.light, a.query.model) == (b.query.x_um, b.query.light, b.query.model)
        np.testing.assert_array_equal(a.lambdas_um, b.lambdas_um)
    assert wb.observation_loss(estimate, back, "mse")[0] == wb.observation_loss(estimate, observations, "mse")[0]
    with pytest.raises(RuntimeError, match="missing.json"):
        wb.read_observations(str(tmp_path / "missing.json"))


def test_json_round_trip_with_exr_references(tmp_path, rng):
    # references='exr': float EXR files in obs/ beside obs.json (what `wavebrdf recover
    # --save-observations` writes); values that are floats read back exactly.
    _, _, _, observations = make_case(rng, 3)
    observations = [wb.Observation(o.query, np.asarray(o.reference).astype(np.float32).astype(np.float64))
                    for o in observations]
    path = tmp_path / "obs.json"
    wb.write_observations(str(path), observations, references="exr")
    assert sorted(p.name for p in (tmp_path / "obs").iterdir()) == ["slice_0000.exr", "slice_0001.exr"]
    back = wb.read_observations(str(path))
    for a, b in zip(observations, back):
        np.testing.assert_array_equal(a.reference, b.reference)
        np.testing.assert_array_equal(a.lambdas_um, b.lambdas_um)
    with pytest.raises(ValueError, match="references"):
        wb.write_observations(str(path), observations, references="png")


def test_write_observations_replaces_only_regular_files(tmp_path, rng):
    # A FIFO or a symbolic link is refused and stays what it was (the temp-and-rename write
    # used to replace it with a regular file); no temporary is left.
    import os
    import stat
    _, _, _, observations = make_case(rng, None)
    fifo = tmp_path / "fifo.json"
    os.mkfifo(fifo)
    (tmp_path / "target.json").write_text("keep")
    link = tmp_path / "link.json"
    link.symlink_to(tmp_path / "target.json")
    for path in (fifo, link):
        with pytest.raises(RuntimeError, match="not a regular file; refusing to replace it"):
            wb.write_observations(str(path), observations)
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode)
    assert link.is_symlink() and (tmp_path / "target.json").read_text() == "keep"
    assert not [p for p in os.listdir(tmp_path) if ".tmp" in p]
