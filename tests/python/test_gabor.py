"""GaborRep: the kernels of a footprint against the definitions of docs/model.md §3-4 computed here in NumPy,
the inverse transform back to heights, and rendering from kernels."""
import numpy as np
import pytest

import wavebrdf as wb


def periodic_offset(index, centre, texel, count):
    period = count * texel
    d = (index + 0.5) * texel - centre
    return d - period * np.floor(d / period + 0.5)


@pytest.mark.parametrize("x,y,sigma_p", [(5.0, 7.0, 1.5), (0.2, 11.9, 2.0), (3.0, 3.0, 40.0)],
                         ids=["inside", "across-the-seam", "covers-all"])
def test_kernels_follow_the_model(rng, x, y, sigma_p):
    texel, vscale = 0.8, 1.7
    v = rng.normal(size=(14, 16))
    hf = wb.Heightfield(v, texel_um=texel, vscale=vscale)
    rep = wb.GaborRep(hf, x_um=x, y_um=y, sigma_p_um=sigma_p)
    assert len(rep) == rep.size and rep.shape == (14, 16)
    assert rep.sigma_um == pytest.approx(texel / 2)
    # The cut: every texel whose nearest periodic image is within 3 sigma_p, each once.
    dx = periodic_offset(np.arange(14), x, texel, 14)[:, None] * np.ones((1, 16))
    dy = periodic_offset(np.arange(16), y, texel, 16)[None, :] * np.ones((14, 1))
    inside = dx ** 2 + dy ** 2 <= (3 * sigma_p) ** 2
    np.testing.assert_array_equal(rep.covered, inside)
    assert rep.size == inside.sum()
    assert len(set(zip(rep.row.tolist(), rep.col.tolist()))) == rep.size
    r, c = rep.row, rep.col
    np.testing.assert_allclose(rep.dx_um, dx[r, c], atol=1e-12)
    np.testing.assert_allclose(rep.dy_um, dy[r, c], atol=1e-12)
    np.testing.assert_allclose(rep.positions_um, np.stack([x + dx[r, c], y + dy[r, c]], axis=1), atol=1e-12)
    # Window weight c(d) w^2 with c(d) = exp(-d^2 / (2 sigma_p^2)) / (sqrt(pi) sigma_p).
    d2 = dx[r, c] ** 2 + dy[r, c] ** 2
    np.testing.assert_allclose(rep.weight, np.exp(-d2 / (2 * sigma_p ** 2)) / (np.sqrt(np.pi) * sigma_p) * texel ** 2,
                               rtol=1e-12)
    np.testing.assert_allclose(rep.height_um, vscale * texel * v[r, c], rtol=1e-12)
    sx = 0.5 * vscale * (np.roll(v, -1, axis=0) - np.roll(v, 1, axis=0))
    sy = 0.5 * vscale * (np.roll(v, -1, axis=1) - np.roll(v, 1, axis=1))
    np.testing.assert_allclose(rep.slope_x, sx[r, c], rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(rep.slope_y, sy[r, c], rtol=1e-12, atol=1e-14)
    for name in ("row", "dx_um", "weight", "height_um", "slope_x"):
        assert not getattr(rep, name).flags.writeable


def test_inverse_transform(rng):
    v = rng.normal(size=(10, 12))
    hf = wb.Heightfield(v, texel_um=0.6, vscale=0.35)
    rep = wb.GaborRep(hf, x_um=3.0, y_um=3.5, sigma_p_um=0.8)
    assert 0 < rep.size < v.size
    h = rep.to_heights()
    covered = rep.covered
    np.testing.assert_allclose(h[covered], v[covered], rtol=1e-12)
    assert np.isnan(h[~covered]).all()
    assert (rep.to_heights(fill=0.0)[~covered] == 0).all()
    # Modified kernel heights map back through h = H / (vscale * texel_um).
    new_h_um = rep.height_um + 0.21
    moved = rep.to_heightfield(height_um=new_h_um, base=hf)
    np.testing.assert_allclose(moved.values[covered], v[covered] + 0.21 / (0.35 * 0.6), rtol=1e-12)
    np.testing.assert_array_equal(moved.values[~covered], v[~covered])
    assert moved.texel_um == 0.6 and moved.vscale == 0.35
    with pytest.raises(ValueError, match="base="):
        rep.to_heightfield()
    with pytest.raises(ValueError, match="height_um has shape"):
        rep.to_heights(height_um=np.zeros(rep.size + 1))
    whole = wb.GaborRep(hf, sigma_p_um=50.0)  # 3 sigma_p spans the tile; <= 10 periods (validate_footprint)
    np.testing.assert_allclose(whole.to_heightfield().values, v, rtol=1e-12)
    flat = wb.GaborRep(wb.Heightfield(v, vscale=0.0), sigma_p_um=1.0)
    with pytest.raises(ValueError, match="vscale"):
        flat.to_heights()


@pytest.mark.parametrize("model,spectral", [("OHS", None), ("GHS", 3), ("Kirchhoff", None)])
def test_render_from_kernels_equals_render_from_heights(rng, model, spectral):
    hf = wb.Heightfield(rng.normal(0, 0.4, size=(12, 12)))
    q = wb.Query(x_um=4.0, y_um=6.0, sigma_p_um=2.0, light=(0.1, 0.2), model=model, spectral=spectral)
    rep = wb.GaborRep(hf, q)
    assert (rep.x_um, rep.y_um, rep.sigma_p_um) == (4.0, 6.0, 2.0)
    a = wb.render(rep, q, 16)
    b = wb.render(hf, q, 16)
    np.testing.assert_allclose(a, b, rtol=0, atol=1e-12 * b.max())
    a32 = wb.render(rep, q, 16, precision="float")
    assert a32.dtype == np.float32
    np.testing.assert_allclose(a32, b, rtol=0, atol=1e-4 * b.max())
    other = q.copy()
    other.x_um = 5.0
    with pytest.raises(ValueError, match="differs from the GaborRep"):
        wb.render(rep, other, 16)


def test_defaults_and_errors(rng):
    hf = wb.Heightfield(rng.normal(size=(8, 6)), texel_um=2.0)
    rep = wb.GaborRep(hf)
    assert (rep.x_um, rep.y_um, rep.sigma_p_um) == (8.0, 6.0, 10.0)
    with pytest.raises(ValueError, match="sigma_p_um"):
        wb.GaborRep(hf, sigma_p_um=0.0)
    with pytest.raises(ValueError, match="x_um"):
        wb.GaborRep(hf, x_um=float("nan"))
    assert "kernels" in repr(rep)
