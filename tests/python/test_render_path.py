"""path= and tolerance= wherever render options are taken: they reach the library (the fft path,
refused by the library until its engine is merged, is refused naming it; the direct and separable
paths give the library's slices), and bad values are refused with a ValueError naming the keyword.
(The lead flips the fft checks when the engine lands.)"""
import numpy as np
import pytest

import wavebrdf as wb


def heights(rng, n=12):
    return rng.normal(0.0, 0.4, (n, n))


def fft_refused(call):
    with pytest.raises(ValueError, match="fft path"):
        call()


def test_every_function_passes_the_path_and_tolerance_on(rng):
    h = heights(rng)
    hf = wb.Heightfield(h, texel_um=0.5)
    q = wb.Query(x_um=2.0, sigma_p_um=1.5, light=(0.1, 0.2))
    w = rng.normal(size=(8, 8, 3))
    o = wb.Observation(q, wb.render(hf, q, 8)[..., 0])
    kw = dict(path="fft", tolerance=1e-4)
    fft_refused(lambda: wb.render_slice(h, resolution=8, texel_um=0.5, **kw))
    fft_refused(lambda: wb.render_slice(np.stack([h, h]), resolution=8, **kw))  # the batch path
    fft_refused(lambda: wb.slice_gradient(h, w, resolution=8, **kw))
    fft_refused(lambda: wb.slice_gradient(np.stack([h, h]), np.stack([w, w]), resolution=8, **kw))
    fft_refused(lambda: wb.render(hf, q, 8, **kw))
    fft_refused(lambda: wb.render(wb.GaborRep(hf, q.x_um, q.y_um, q.sigma_p_um), q, 8, **kw))
    fft_refused(lambda: wb.gradient(hf, q, w, **kw))
    fft_refused(lambda: o.render(hf, **kw))
    fft_refused(lambda: wb.observation_loss(hf, [o], **kw))
    fft_refused(lambda: wb.render_table(hf, q, lights=2, resolution=8, **kw))
    fft_refused(lambda: wb.invert(size=4, resolution=8, epochs=0, quiet=True, **kw))


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

