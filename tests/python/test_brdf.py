"""render_slice and slice_gradient: layout, precision, symmetries, the spectral mapping, finite
differences, argument errors, and equality with the command line."""
import os
import subprocess

import numpy as np
import pytest

import wavebrdf as wb

# A small rough surface with a footprint that covers most of it (fast, and every texel matters).
N = 12
OPTS = dict(resolution=16, sigma_p_um=2.0, x_um=6.0, y_um=6.0)


def heights(rng, rows=N, cols=N, scale=0.4):
    return rng.normal(0.0, scale, (rows, cols))


def test_shape_dtype_and_layout(rng):
    h = heights(rng)
    s = wb.render_slice(h, **OPTS)
    assert s.shape == (16, 16, 3) and s.dtype == np.float64
    assert s.flags.c_contiguous and s.flags.writeable
    s32 = wb.render_slice(h.astype(np.float32), **OPTS)
    assert s32.dtype == np.float32
    # One wavelength: R = G = B, f_r >= 0, zero outside the projected disk.
    assert np.array_equal(s[..., 0], s[..., 1]) and np.array_equal(s[..., 0], s[..., 2])
    assert (s >= 0).all() and s.max() > 0
    w = (np.arange(16) + 0.5) / 16 * 2 - 1
    outside = w[:, None] ** 2 + w[None, :] ** 2 > 1
    assert (s[outside] == 0).all() and (s[~outside] > 0).any()
    # Single precision agrees with double to single-precision accuracy.
    np.testing.assert_allclose(s32, s, rtol=0, atol=2e-4 * s.max())


def test_non_contiguous_and_list_input(rng):
    h = heights(rng)
    ref = wb.render_slice(h, **OPTS)
    fortran = np.asfortranarray(h)
    strided = np.zeros((N, 2 * N))
    strided[:, ::2] = h
    assert np.array_equal(wb.render_slice(fortran, **OPTS), ref)
    assert np.array_equal(wb.render_slice(strided[:, ::2], **OPTS), ref)
    assert np.array_equal(wb.render_slice(h.tolist(), **OPTS), ref)


def test_rows_are_x_periodic_shift(rng):
    # Rolling the heights by k texels along rows (x) and moving the footprint by k texel widths
    # along x renders the same slice (periodic surface; a transposed binding would fail).
    h = heights(rng)
    texel = 0.7
    a = wb.render_slice(h, **dict(OPTS, texel_um=texel, x_um=3.0, y_um=5.0))
    b = wb.render_slice(np.roll(h, 3, axis=0), **dict(OPTS, texel_um=texel, x_um=3.0 + 3 * texel, y_um=5.0))
    c = wb.render_slice(np.roll(h, 3, axis=1), **dict(OPTS, texel_um=texel, x_um=3.0 + 3 * texel, y_um=5.0))
    np.testing.assert_allclose(b, a, rtol=0, atol=1e-10 * a.max())
    assert np.abs(c - a).max() > 1e-3 * a.max()


def test_mirror_symmetry(rng):
    # Mirroring the surface along x (rows) at normal incidence mirrors the slice along its rows.
    h = heights(rng)
    period = N * 1.0
    a = wb.render_slice(h, **dict(OPTS, x_um=4.0))
    b = wb.render_slice(h[::-1, :], **dict(OPTS, x_um=period - 4.0))
    np.testing.assert_allclose(b, a[::-1, :, :], rtol=0, atol=1e-10 * a.max())


def test_height_offset_is_invisible(rng):
    h = heights(rng)
    a = wb.render_slice(h, **OPTS)
    b = wb.render_slice(h + 3.25, **OPTS)
    np.testing.assert_allclose(b, a, rtol=0, atol=1e-9 * a.max())


def test_spectral_is_the_cie_mix_of_single_wavelengths(rng):
    # spectral=N: channel c = sum_l M[c, l] f(lambda_l), with the library's wavelengths and weights.
    h = heights(rng)
    lambdas = wb.spectral_wavelengths_um(5)
    np.testing.assert_allclose(lambdas, 0.36 + (np.arange(5) + 0.5) * 0.47 / 5)
    mix = wb.spectral_to_srgb_weights(lambdas)
    assert mix.shape == (3, 5)
    mono = np.stack([wb.render_slice(h, lambda_um=l, **OPTS)[..., 0] for l in lambdas], axis=-1)
    expected = mono @ mix.T
    for spectral in (5, lambdas):
        s = wb.render_slice(h, spectral=spectral, **OPTS)
        np.testing.assert_allclose(s, expected, rtol=0, atol=1e-12 * np.abs(expected).max())
    # A constant spectrum maps to grey.
    np.testing.assert_allclose(mix.sum(axis=1), 1.0, rtol=1e-9)


def test_vscale_and_texel_scaling(rng):
    # Only heights in um = vscale * texel_um * h matter for the phase; so (h, v) and (2h, v/2) agree.
    h = heights(rng)
    a = wb.render_slice(h, vscale=0.8, texel_um=0.9, **OPTS)
    b = wb.render_slice(2 * h, vscale=0.4, texel_um=0.9, **OPTS)
    np.testing.assert_allclose(b, a, rtol=0, atol=1e-10 * a.max())


def loss_of(h, weights, **opts):
    return float(np.sum(weights * wb.render_slice(h, **opts)))


@pytest.mark.parametrize("opts", [
    dict(OPTS),
    dict(OPTS, model="GHS", light=(0.3, -0.2), texel_um=0.8, vscale=0.6),
    dict(OPTS, spectral=4, model="ROHS", x_um=1.0),
    dict(OPTS, spectral=[0.45, 0.55, 0.65], model="Kirchhoff", light=(-0.1, 0.25)),
], ids=["OHS-mono", "GHS-mono-light-scaled", "ROHS-spectral4", "Kirchhoff-spectral-list"])
def test_gradient_matches_finite_differences(rng, opts):
    h = heights(rng)
    weights = rng.uniform(-1.0, 1.0, (16, 16, 3))  # different per channel: tests the channel mapping
    g = wb.slice_gradient(h, weights, **opts)
    assert g.shape == h.shape and g.dtype == np.float64
    # Directional derivative along two random directions (central differences, Richardson).
    for _ in range(2):
        d = rng.normal(0.0, 1.0, h.shape)
        eps = 1e-4
        f = lambda t: loss_of(h + t * d, weights, **opts)  # noqa: E731
        fd1 = (f(eps) - f(-eps)) / (2 * eps)
        fd2 = (f(eps / 2) - f(-eps / 2)) / eps
        fd = (4 * fd2 - fd1) / 3
        assert np.sum(g * d) == pytest.approx(fd, rel=1e-6, abs=1e-9 * np.abs(g).sum())
    # And per entry for a few texels.
    for (i, j) in [(0, 0), (5, 7), (N - 1, 3)]:
        e = np.zeros_like(h)
        e[i, j] = 1.0
        fd = (loss_of(h + 1e-5 * e, weights, **opts) - loss_of(h - 1e-5 * e, weights, **opts)) / 2e-5
        assert g[i, j] == pytest.approx(fd, rel=1e-5, abs=1e-7 * np.abs(g).max())


def test_gradient_single_precision(rng):
    h = heights(rng)
    weights = rng.uniform(0.0, 1.0, (16, 16, 3))
    g64 = wb.slice_gradient(h, weights, **OPTS)
    g32 = wb.slice_gradient(h.astype(np.float32), weights.astype(np.float32), **OPTS)
    assert g32.dtype == np.float32 and g32.shape == h.shape
    np.testing.assert_allclose(g32, g64, rtol=0, atol=1e-3 * np.abs(g64).max())


def test_gradient_is_linear_in_weights(rng):
    h = heights(rng)
    w1, w2 = rng.normal(size=(2, 16, 16, 3))
    g = wb.slice_gradient(h, 2 * w1 - 3 * w2, spectral=3, **OPTS)
    g1 = wb.slice_gradient(h, w1, spectral=3, **OPTS)
    g2 = wb.slice_gradient(h, w2, spectral=3, **OPTS)
    np.testing.assert_allclose(g, 2 * g1 - 3 * g2, rtol=0, atol=1e-10 * np.abs(g).max())


BAD = [
    (dict(heights=np.zeros(5)), "heights"),
    (dict(heights=np.zeros((0, 4))), "heights"),
    (dict(heights=np.zeros((4, 4), dtype=np.int64)), "heights"),
    (dict(heights=np.full((4, 4), np.nan)), "heights[0, 0]"),
    (dict(heights=np.array([[0.0, np.inf]] * 2)), "heights[0, 1]"),
    (dict(heights=[["a", "b"]]), "heights"),
    (dict(resolution=0), "resolution"),
    (dict(resolution=9000), "resolution"),
    (dict(texel_um=0.0), "texel_um"),
    (dict(texel_um=float("nan")), "texel_um"),
    (dict(vscale=float("inf")), "vscale"),
    (dict(x_um=float("nan")), "x_um"),
    (dict(y_um=float("inf")), "y_um"),
    (dict(sigma_p_um=-1.0), "sigma_p_um"),
    (dict(lambda_um=0.0), "lambda_um"),
    (dict(lambda_um=-0.5), "lambda_um"),
    (dict(spectral=0), "spectral"),
    (dict(spectral=257), "spectral"),
    (dict(spectral=[]), "spectral"),
    (dict(spectral=[0.5, -0.4]), "spectral"),
    (dict(spectral="many"), "spectral"),
    (dict(spectral=3, lambda_um=0.5), "lambda_um and spectral"),
    (dict(light=(1.0, 0.0)), "light"),
    (dict(light=(0.8, 0.8)), "light"),
    (dict(light=(0.1,)), "light"),
    (dict(light=(float("nan"), 0.0)), "light"),
    (dict(model="ohs2"), "model"),
]


@pytest.mark.parametrize("bad,name", BAD, ids=[b[1] + "-" + str(i) for i, b in enumerate(BAD)])
def test_bad_arguments_raise_value_error(bad, name):
    kwargs = dict(heights=np.zeros((4, 4)), resolution=8)
    kwargs.update(bad)
    with pytest.raises(ValueError) as e:
        wb.render_slice(kwargs.pop("heights"), **kwargs)
    assert name in str(e.value)
    kwargs = dict(heights=np.zeros((4, 4)), resolution=8)
    kwargs.update(bad)
    weights = np.zeros((kwargs["resolution"], kwargs["resolution"], 3)) if 1 <= kwargs["resolution"] <= 8192 else np.zeros((1, 1, 3))
    with pytest.raises(ValueError) as e:
        wb.slice_gradient(kwargs.pop("heights"), weights, **kwargs)
    assert name in str(e.value)


@pytest.mark.parametrize("weights,name", [
    (np.zeros((8, 8)), "weights has shape (8, 8)"),
    (np.zeros((8, 8, 1)), "weights has shape"),
    (np.zeros((7, 8, 3)), "weights has shape"),
    (np.zeros((8, 8, 3), dtype=np.int32), "weights has dtype"),
    # The first pixel inside the unit disk (row 0, column 2 of 8 x 8): outside it weights are ignored.
    (np.full((8, 8, 3), np.nan), "weights[0, 2, 0]"),
])
def test_bad_weights(weights, name):
    with pytest.raises(ValueError) as e:
        wb.slice_gradient(np.zeros((4, 4)), weights, resolution=8)
    assert name in str(e.value)


# Issue 9: values outside a physically meaningful range gave all-zero slices; they are refused
# with the range. 4 x 4 texels of 1 um: sigma_p <= 10 periods = 40 um.
OUT_OF_RANGE = [
    (dict(lambda_um=1e-300), "0.01 to 1000 um"),
    (dict(lambda_um=1e300), "0.01 to 1000 um"),
    (dict(texel_um=1e-300), "0.0001 to 10000 um"),
    (dict(texel_um=1e300), "0.0001 to 10000 um"),
    (dict(vscale=1e-300), "1e-06 <= |vscale| <= 10000"),
    (dict(vscale=-1e300), "1e-06 <= |vscale| <= 10000"),
    (dict(sigma_p_um=1e-300), "1e-06 to 1000000 um"),
    (dict(sigma_p_um=1e9), "1e-06 to 1000000 um"),
    (dict(sigma_p_um=41.0), "10 x the longer tile period = 40 um"),
]


@pytest.mark.parametrize("bad,message", OUT_OF_RANGE, ids=[str(b) for b, _ in OUT_OF_RANGE])
def test_out_of_range_values_name_the_range(bad, message):
    kwargs = dict(resolution=8, x_um=2.0, y_um=2.0, sigma_p_um=1.0)
    kwargs.update(bad)
    with pytest.raises(ValueError, match=message.replace("|", r"\|")):
        wb.render_slice(np.zeros((4, 4)), **kwargs)


def test_positions_a_huge_multiple_of_the_period_away_give_the_same_slice(rng):
    # Issue 9: x_um = 32 + 64e8 gave an all-zero slice (an int overflowed before the position
    # was reduced to the tile). Periods here: 64 x 48 um; every shifted value is an exact double.
    h = heights(rng, 64, 48)
    opts = dict(resolution=16, sigma_p_um=4.0, light=(0.1, -0.2))
    near = wb.render_slice(h, x_um=32.0, y_um=20.0, **opts)
    assert near.max() > 0
    for x, y in [(32 + 64e8, 20.0), (3000000032.0, 20 - 48e8), (32 - 64e13, 20 + 48e13)]:
        np.testing.assert_array_equal(wb.render_slice(h, x_um=x, y_um=y, **opts), near)
        np.testing.assert_array_equal(wb.render_slice(h, x_um=x, y_um=y, model="GHS", **opts),
                                      wb.render_slice(h, x_um=32.0, y_um=20.0, model="GHS", **opts))


def test_resolution_is_required():
    with pytest.raises(TypeError):
        wb.render_slice(np.zeros((4, 4)))


def run_cli(cli, *args):
    result = subprocess.run([cli, *map(str, args)], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    return result


@pytest.mark.parametrize("precision,extra", [
    ("double", dict(lambda_um=0.55)),
    ("double", dict(spectral=6, model="GHS", light=(0.25, -0.1))),
    ("float", dict(spectral=4, model="ROHS", light=(-0.3, 0.2))),
    ("float", dict(model="Kirchhoff")),
], ids=["double-mono-OHS", "double-spectral-GHS", "float-spectral-ROHS", "float-mono-Kirchhoff"])
def test_python_and_cli_render_the_same_slice(tmp_path, cli, precision, extra):
    # Heights generated by the CLI's own generator and read back by the module (EXR), so the
    # two sides share nothing but the file.
    exr = tmp_path / "h.exr"
    run_cli(cli, "heightfield", "--type", "isotropic", "--size", "24x20", "--rms-height-um", 0.3,
            "--correlation-um", 2, "--seed", 5, "--no-png", "--quiet", "--out", exr)
    hf = wb.Heightfield.from_exr(str(exr), texel_um=0.8, vscale=1.3)
    assert hf.shape == (24, 20)
    opts = dict(texel_um=0.8, vscale=1.3, x_um=7.0, y_um=11.5, sigma_p_um=3.0, resolution=24, **extra)
    args = ["render", "--heightfield", exr, "--texel-um", 0.8, "--vscale", 1.3, "--x-um", 7.0, "--y-um", 11.5,
            "--sigma-p-um", 3.0, "--resolution", 24, "--precision", precision, "--quiet",
            "--out", tmp_path / "slice.npy"]
    if "lambda_um" in extra:
        args += ["--lambda-um", extra["lambda_um"]]
    if "spectral" in extra:
        args += ["--spectral", extra["spectral"]]
    if "model" in extra:
        args += ["--model", extra["model"]]
    if "light" in extra:
        args += ["--light-x", extra["light"][0], "--light-y", extra["light"][1]]
    run_cli(cli, *args)
    from_cli = np.load(tmp_path / "slice.npy")
    heights_in = hf.values if precision == "double" else hf.values.astype(np.float32)
    from_python = wb.render_slice(heights_in, **opts)
    assert from_python.shape == from_cli.shape == (24, 24, 3)
    assert from_python.dtype == (np.float64 if precision == "double" else np.float32)
    peak = from_cli.max()
    assert peak > 0
    # The same code on the same input: equal up to the order of floating-point sums.
    tol = 1e-12 if precision == "double" else 1e-6
    np.testing.assert_allclose(from_python, from_cli, rtol=0, atol=tol * peak)
    # The object API gives the same too.
    q = wb.Query(x_um=7.0, y_um=11.5, sigma_p_um=3.0, light=extra.get("light", (0, 0)),
                 model=extra.get("model", "OHS"), lambda_um=extra.get("lambda_um"), spectral=extra.get("spectral"))
    np.testing.assert_allclose(wb.render(hf, q, 24, precision=precision), from_cli, rtol=0, atol=tol * peak)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_slice_plan_matches_render_slice_and_slice_gradient(dtype):
    # The internal plan wavebrdf.torch uses: its forward is render_slice and its adjoint is
    # slice_gradient, exactly.
    rng = np.random.default_rng(3)
    heights = (0.3 * rng.standard_normal((12, 12))).astype(dtype)
    options = dict(resolution=10, sigma_p_um=3.0, x_um=5.0, y_um=6.0, spectral=3, light=(0.1, 0.0))
    plan = wb._core._SlicePlan(heights, **options)
    out = plan.forward()
    assert out.dtype == dtype
    np.testing.assert_array_equal(out, wb.render_slice(heights, **options))
    weights = rng.standard_normal((10, 10, 3))
    gradient = plan.adjoint(weights)
    assert gradient.dtype == dtype and gradient.shape == heights.shape
    np.testing.assert_array_equal(gradient, wb.slice_gradient(heights, weights, **options))
    with pytest.raises(ValueError, match="weights"):
        plan.adjoint(np.zeros((3, 3, 3)))
