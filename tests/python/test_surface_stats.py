"""wb.surface_stats / surface_psd / surface_acf, wb.condition_surface, Heightfield.from_um and
hf.conditioned: against values published by another program for a surface anyone can rebuild
(surfalize's test fixture, whose height parameters surfalize checks against Gwyddion and
MountainsMap), against closed forms, and their errors."""
import math

import numpy as np
import pytest

import wavebrdf as wb

KEYS = {"Sa", "Sq", "Sp", "Sv", "Sz", "Ssk", "Sku", "Sdq", "Sdr", "Sal", "Str", "Std"}


def surfalize_fixture():
    """surfalize's tests/conftest.py `surface` (fredericjs/surfalize): 1000 x 700 points at
    0.1 um, a sinusoid of period 20 um, a modulated ripple and Gaussian noise drawn by NumPy's
    legacy generator with seed 0 (a frozen stream). Rebuilt from the description, not copied."""
    state = np.random.RandomState(0)
    step = 0.1
    period = 20 / step
    period_ripple = 1 / step
    x, y = np.meshgrid(np.arange(1000), np.arange(700))
    z = np.sin(x / period * 2 * np.pi)
    z += 0.5 * (np.sin((x - period / 2) / period * 2 * np.pi) + 1) * 0.3 * np.sin(
        (np.sin(y / 10) + x) / period_ripple * 2 * np.pi)
    z += state.normal(size=z.shape) / 5
    return z, step


def test_parameters_match_surfalize_published_values():
    z, step = surfalize_fixture()
    # The image's axis 0 is y; a Heightfield's axis 0 is x, so pass the transpose.
    p = wb.surface_stats(wb.Heightfield.from_um(z.T, step))
    assert KEYS <= set(p)
    # surfalize tests/test_parameters.py (checked there to 1e-6 absolute).
    for key, value in {"Sa": 0.653132, "Sq": 0.745961, "Sp": 1.854956, "Sv": 1.998661, "Sz": 3.853617,
                       "Ssk": -0.08144, "Sku": 1.818014}.items():
        assert p[key] == pytest.approx(value, abs=2e-6), key
    # Sdq: surfalize divides both directions' sums of squared forward differences by all
    # 700 x 1000 points, we average over the points that have both (as SurfaceTopography).
    assert p["Sdq"] == pytest.approx(4.079605, rel=1e-3)
    # Sdr: surfalize doubles one triangle per cell; we add the cell's two triangles.
    assert p["Sdr"] == pytest.approx(276.112693, rel=5e-3)
    # Sal, Str: the same ACF (unbiased, zero padded); surfalize's nearest point of the lobe's
    # edge against our rays every 0.5 degrees.
    assert p["Sal"] == pytest.approx(4.347147, rel=0.02)
    # Along the ridges (y) the ACF stays above 0.2 over the whole grid. We search a ray out to
    # half the extent (349 lags of 0.1 um; rays a few degrees off y reach a little further) and
    # say the bound; surfalize's 0.062759 is the same ratio with the whole extent (699 lags):
    # both are bounds, consistent with each other.
    assert not p["acf_decayed_everywhere"]
    assert p["Str"] == pytest.approx(p["Sal"] / (349 * 0.1), rel=0.02)
    assert p["Sal"] / (699 * 0.1) == pytest.approx(0.062759, rel=0.02)
    # Its ridges run along y (the sinusoid varies along x): the lay is at 90 degrees.
    assert p["Std"] == pytest.approx(90.0, abs=1.0)


def test_sinusoid_and_psd_parseval(rng):
    a, period, texel = 0.2, 8.0, 0.5
    i = np.arange(64)[:, None] * np.ones((1, 48))
    hf = wb.Heightfield.from_um(a * np.cos(2 * np.pi * i * texel / period), texel)
    p = wb.surface_stats(hf)
    assert p["Sq"] == pytest.approx(a / math.sqrt(2), rel=1e-12)
    assert p["Sku"] == pytest.approx(1.5, rel=1e-10)
    assert p["Std"] == pytest.approx(90.0, abs=0.5)  # varies along x (axis 0): lay along y
    noise = wb.Heightfield.from_um(rng.normal(0, 0.05, (40, 30)), 0.25)
    psd = wb.surface_psd(noise)
    sq = wb.surface_stats(noise)["Sq"]
    total = psd["psd_2d_um4"].sum() * psd["dq_x_per_um"] * psd["dq_y_per_um"] / (2 * np.pi) ** 2
    assert total == pytest.approx(sq ** 2, rel=1e-10)
    acf = wb.surface_acf(noise)
    assert acf["acf_2d"].shape == (59, 79)
    assert acf["acf_2d"][29, 39] == pytest.approx(1.0)
    assert acf["acf"][0] == pytest.approx(1.0)


def test_condition_surface_fills_detrends_and_refuses(rng):
    y, x = np.mgrid[0:30, 0:40]
    z = 0.01 * x - 0.02 * y + rng.normal(0, 1e-3, (30, 40))
    z[5:9, 10:14] = np.nan
    with pytest.raises(ValueError, match="16 of 1200 points"):
        wb.condition_surface(z, 0.5, 1.0, resample_um=0.5)
    out = wb.condition_surface(z, 0.5, 1.0, detrend="plane", fill="harmonic", resample_um=0.5, periodic="smooth")
    assert out["dx_um"] == out["dy_um"] == 0.5
    assert out["heights_um"].shape == (59, 40)
    assert np.isfinite(out["heights_um"]).all()
    assert [s.split(":")[0] for s in out["steps"]] == ["detrend", "fill", "resample", "periodic"]
    assert out["seam_ratio_after"] < out["seam_ratio_before"]
    with pytest.raises(ValueError, match="fill 'zero'"):
        wb.condition_surface(z, 0.5, fill="zero")


def test_from_um_and_conditioned():
    heights = np.add.outer(np.arange(16) * 0.01, np.arange(12) * 0.02)
    hf = wb.Heightfield.from_um(heights, 0.5, vscale=2.0)
    assert hf.texel_um == 0.5 and hf.vscale == 2.0
    np.testing.assert_allclose(hf.values * 2.0 * 0.5, heights, rtol=1e-15)
    flat = hf.conditioned(detrend="plane")
    assert wb.surface_stats(flat)["Sq"] < 1e-12
    cropped = hf.conditioned(crop=(2, 3, 8, 5), periodic="mirror")
    assert (cropped.rows, cropped.cols) == (16, 10)
    with pytest.raises(ValueError, match="NaN|finite"):
        wb.Heightfield.from_um(np.full((4, 4), np.nan), 1.0)
