"""path= and tolerance= wherever render options are taken: they reach the library (the fft path
gives the direct sum's values within its tolerance; the direct and separable paths give the
library's slices), and bad values are refused with a ValueError naming the keyword."""
import numpy as np
import pytest

import wavebrdf as wb


def heights(rng, n=12):
    return rng.normal(0.0, 0.4, (n, n))


def fft_matches_direct(call):
    """call(**options) on the fft path (tolerance 1e-4) and on the direct path (no pruning): the
    same result within the tolerance, relative to the largest value."""
    fft = call(path="fft", tolerance=1e-4)
    direct = call(path="direct")
    if isinstance(fft, tuple):
        fft, direct = fft[0], direct[0]
    fft, direct = np.asarray(fft, dtype=float), np.asarray(direct, dtype=float)
    assert fft.shape == direct.shape
    assert np.max(np.abs(fft - direct)) <= 2e-4 * np.max(np.abs(direct))


def test_every_function_takes_the_fft_path(rng):
    h = heights(rng)
    hf = wb.Heightfield(h, texel_um=0.5)
    q = wb.Query(x_um=2.0, sigma_p_um=1.5, light=(0.1, 0.2))
    w = rng.normal(size=(8, 8, 3))
    o = wb.Observation(q, wb.render(hf, q, 8)[..., 0])
    fft_matches_direct(lambda **kw: wb.render_slice(h, resolution=8, texel_um=0.5, **kw))
    fft_matches_direct(lambda **kw: wb.render_slice(np.stack([h, h]), resolution=8, **kw))  # the batch path
    fft_matches_direct(lambda **kw: wb.slice_gradient(h, w, resolution=8, **kw))
    fft_matches_direct(lambda **kw: wb.slice_gradient(np.stack([h, h]), np.stack([w, w]), resolution=8, **kw))
    fft_matches_direct(lambda **kw: wb.render(hf, q, 8, **kw))
    fft_matches_direct(lambda **kw: wb.render(wb.GaborRep(hf, q.x_um, q.y_um, q.sigma_p_um), q, 8, **kw))
    fft_matches_direct(lambda **kw: wb.gradient(hf, q, w, **kw))
    fft_matches_direct(lambda **kw: o.render(hf, **kw))
    other = wb.Heightfield(h * 1.1, texel_um=0.5)  # o is hf's own slice: a loss of about 0 compares nothing
    fft_matches_direct(lambda **kw: wb.observation_loss(other, [o], **kw))
    fft_matches_direct(lambda **kw: wb.render_table(hf, q, lights=2, resolution=8, **kw).values)
    wb.invert(size=4, resolution=8, epochs=0, quiet=True, path="fft", tolerance=1e-4)


@pytest.mark.parametrize("bad, message", [
    (dict(path="sideways"), "path 'sideways' is unknown; expected auto, separable, fft or direct"),
    (dict(path="Direct"), "path 'Direct'"),
    (dict(tolerance=0.5), "tolerance 0.5 is out of range; expected 1e-12 to 1e-2"),
    (dict(tolerance=1e-13), "tolerance 1e-13 is out of range"),
    (dict(tolerance=float("nan")), "tolerance nan is out of range"),
])
def test_bad_values_are_refused_naming_the_keyword(rng, bad, message):
    h = heights(rng)
    hf = wb.Heightfield(h)
    q = wb.Query(sigma_p_um=2.0)
    for call in (lambda: wb.render_slice(h, resolution=8, **bad),
                 lambda: wb.slice_gradient(h, np.ones((8, 8, 3)), resolution=8, **bad),
                 lambda: wb.render(hf, q, 8, **bad),
                 lambda: wb.render_table(hf, q, lights=2, resolution=8, **bad),
                 lambda: wb.invert(size=4, resolution=8, epochs=0, quiet=True, **bad)):
        with pytest.raises(ValueError, match=message.replace("(", r"\(")) as e:
            call()
        assert "\n" not in str(e.value)


def test_direct_and_separable_give_the_librarys_slices(rng):
    h = heights(rng)
    hf = wb.Heightfield(h)
    # GHS: the direct path, with a tolerance (which the direct path does not need).
    q = wb.Query(x_um=3.0, sigma_p_um=2.0, light=(0.3, 0.0), model="GHS")
    direct = wb.render_slice(h, resolution=10, x_um=3.0, sigma_p_um=2.0, light=(0.3, 0.0), model="GHS",
                             path="direct", tolerance=1e-3)
    np.testing.assert_array_equal(direct, wb.render(hf, q, 10, path="direct"))
    # OHS: the separable product and the direct sum agree closely but are two computations.
    q = wb.Query(x_um=3.0, sigma_p_um=2.0)
    sep = wb.render(hf, q, 10, path="separable")
    dir_ = wb.render(hf, q, 10, path="direct")
    np.testing.assert_allclose(sep, dir_, rtol=1e-6, atol=1e-9 * sep.max())
    assert not np.array_equal(sep, dir_)  # the path really changed
    np.testing.assert_array_equal(wb.render_slice(h, resolution=10, x_um=3.0, sigma_p_um=2.0, path="separable"),
                                  sep)

