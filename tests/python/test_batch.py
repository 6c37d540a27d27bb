"""render_slice and slice_gradient over NumPy leading batch axes (the library's batch API):
shapes and the broadcast rule, equality with a loop of single calls, the summed gradient, finite
differences, errors naming the argument and the shapes, and wavebrdf.torch batched."""
import numpy as np
import pytest

import wavebrdf as wb

N = 10
OPTS = dict(resolution=12, sigma_p_um=2.0)


def stack(rng, *lead, dtype=np.float64):
    return rng.normal(0.0, 0.3, lead + (N, N)).astype(dtype)


def single(h, **kw):
    return wb.render_slice(h, **dict(OPTS, **kw))


def test_leading_heights_axes_equal_a_loop_of_single_calls(rng):
    h = stack(rng, 2, 3)
    s = wb.render_slice(h, x_um=4.0, y_um=5.0, spectral=3, **OPTS)
    assert s.shape == (2, 3, 12, 12, 3) and s.dtype == np.float64 and s.flags.c_contiguous
    for i in range(2):
        for j in range(3):
            np.testing.assert_allclose(s[i, j], single(h[i, j], x_um=4.0, y_um=5.0, spectral=3), rtol=1e-12, atol=0)


def test_float32_batches_stay_float32(rng):
    h = stack(rng, 3, dtype=np.float32)
    s = wb.render_slice(h, model="GHS", light=(0.2, 0.1), **OPTS)
    assert s.dtype == np.float32 and s.shape == (3, 12, 12, 3)
    for i in range(3):
        np.testing.assert_allclose(s[i], single(h[i], model="GHS", light=(0.2, 0.1)), rtol=1e-6,
                                   atol=1e-6 * s.max())


def test_lights_and_positions_broadcast_against_heights(rng):
    h = stack(rng, 2, 1)                      # (2, 1, N, N): batch (2, 1)
    light = np.array([[0.0, 0.0], [0.3, -0.2], [-0.1, 0.4]])  # (3, 2): batch (3,)
    x = np.array([[3.0], [7.5]])              # (2, 1)
    s = wb.render_slice(h, light=light, x_um=x, y_um=4.0, model="Kirchhoff", **OPTS)
    assert s.shape == (2, 3, 12, 12, 3)
    for i in range(2):
        for l in range(3):
            np.testing.assert_allclose(s[i, l], single(h[i, 0], light=light[l], x_um=x[i, 0], y_um=4.0,
                                                       model="Kirchhoff"), rtol=1e-12, atol=0)
    # One heightfield, a grid of positions (x (3, 1) against y (4,)): a (3, 4) batch.
    xs, ys = np.array([[1.0], [4.0], [8.0]]), np.array([0.0, 2.0, 5.0, 9.0])
    s = wb.render_slice(h[0, 0], x_um=xs, y_um=ys, **OPTS)
    assert s.shape == (3, 4, 12, 12, 3)
    np.testing.assert_allclose(s[2, 1], single(h[0, 0], x_um=8.0, y_um=2.0), rtol=1e-12, atol=0)
    # Lists and tensors-like sequences are arrays too.
    s = wb.render_slice(h[0, 0], light=[[0.1, 0.0], [0.0, 0.1]], **OPTS)
    assert s.shape == (2, 12, 12, 3)


def test_a_single_query_keeps_its_shapes_and_values(rng):
    h = stack(rng)
    s = wb.render_slice(h, x_um=np.float64(4.0), y_um=np.array(5.0), light=np.array([0.1, 0.2]), **OPTS)
    assert s.shape == (12, 12, 3)
    np.testing.assert_array_equal(s, single(h, x_um=4.0, y_um=5.0, light=(0.1, 0.2)))
    one = wb.render_slice(h[None], x_um=4.0, y_um=5.0, light=(0.1, 0.2), **OPTS)
    assert one.shape == (1, 12, 12, 3)
    np.testing.assert_allclose(one[0], s, rtol=1e-12, atol=0)
    g = wb.slice_gradient(h, np.ones((12, 12, 3)), x_um=np.float64(4.0), **OPTS)
    assert g.shape == (N, N)


def test_gradient_sums_over_the_items_that_share_heights(rng):
    h = stack(rng, 2, 1)
    light = np.array([[0.0, 0.0], [0.25, 0.1]])
    opts = dict(OPTS, light=light, x_um=4.0, y_um=6.0, spectral=[0.45, 0.6])
    w = rng.normal(size=(2, 2, 12, 12, 3))
    g = wb.slice_gradient(h, w, **opts)
    assert g.shape == h.shape and g.dtype == np.float64
    for i in range(2):
        expected = sum(wb.slice_gradient(h[i, 0], w[i, l], **dict(opts, light=light[l])) for l in range(2))
        np.testing.assert_allclose(g[i, 0], expected, rtol=0, atol=1e-12 * np.abs(expected).max())
    # One heightfield, several lights: one gradient, the sum.
    g1 = wb.slice_gradient(h[0, 0], w[0], **opts)
    assert g1.shape == (N, N)
    np.testing.assert_allclose(g1, g[0, 0], rtol=0, atol=1e-12 * np.abs(g1).max())


def test_gradient_matches_finite_differences(rng):
    h = stack(rng, 2)
    opts = dict(OPTS, light=np.array([[0.0, 0.0], [0.2, -0.3]]), x_um=5.0, y_um=5.0, model="GHS")
    w = rng.uniform(size=(2, 12, 12, 3))
    g = wb.slice_gradient(h, w, **opts)
    eps = 1e-5
    for index in [(0, 1, 2), (1, 5, 5), (1, 9, 0)]:
        plus, minus = h.copy(), h.copy()
        plus[index] += eps
        minus[index] -= eps
        fd = ((wb.render_slice(plus, **opts) - wb.render_slice(minus, **opts)) * w).sum() / (2 * eps)
        assert g[index] == pytest.approx(fd, rel=1e-5, abs=1e-6 * np.abs(g).max())


def test_empty_batches(rng):
    s = wb.render_slice(np.zeros((0, N, N)), **OPTS)
    assert s.shape == (0, 12, 12, 3)
    g = wb.slice_gradient(np.zeros((0, N, N)), np.zeros((0, 12, 12, 3)), **OPTS)
    assert g.shape == (0, N, N)
    s = wb.render_slice(np.zeros((N, N)), light=np.zeros((0, 2)), **OPTS)
    assert s.shape == (0, 12, 12, 3)


@pytest.mark.parametrize("kwargs,message", [
    (dict(heights=np.zeros((3, N, N)), light=np.zeros((4, 2))), "batch shapes do not broadcast: heights (3,), light (4,)"),
    (dict(heights=np.zeros((3, N, N)), x_um=np.zeros(2)), "x_um (2,)"),
    (dict(heights=np.zeros((3, N, N)), light=np.zeros(3)), "light has shape (3,); expected (2,) or (..., 2)"),
    (dict(heights=np.zeros((2, N, N)), light=np.array([[0.0, 0.0], [0.9, 0.9]])), "light[1]"),
    (dict(heights=np.zeros((2, N, N)), y_um=np.array([1.0, np.nan])), "y_um[1]"),
    (dict(heights=np.zeros((2, N, N)), x_um=["a", "b"]), "x_um"),
    (dict(heights=np.zeros((2, 0, N))), "heights has shape (2, 0, 10)"),
    (dict(heights=np.zeros((2, N, N), dtype=np.int64)), "heights has dtype"),
    (dict(heights=np.zeros((2, N, N)), resolution=0), "resolution"),
    (dict(heights=np.zeros((2, N, N)), sigma_p_um=-1.0), "sigma_p_um"),
])
def test_bad_batches_raise_value_error_naming_the_argument(kwargs, message):
    kwargs = dict(OPTS, **kwargs)
    with pytest.raises(ValueError) as e:
        wb.render_slice(kwargs.pop("heights"), **kwargs)
    assert message in str(e.value)


def test_bad_batch_weights_name_the_expected_shape():
    with pytest.raises(ValueError, match=r"weights has shape \(3, 12, 12, 3\); expected \(2, 12, 12, 3\)"):
        wb.slice_gradient(np.zeros((2, N, N)), np.zeros((3, 12, 12, 3)), **OPTS)


def test_hostile_batch_sizes_are_refused_before_allocating():
    # 1e6 x 1e6 items (broadcast from two small arrays) at 8192^2: a MemoryError at once.
    x = np.zeros((1000000, 1))
    y = np.zeros(1000000)
    with pytest.raises(MemoryError, match="render_slice of batch shape"):
        wb.render_slice(np.zeros((N, N)), x_um=x, y_um=y, resolution=8192)


def test_torch_batched_forward_backward_and_gradcheck():
    torch = pytest.importorskip("torch")
    import wavebrdf.torch as wt
    g = torch.Generator().manual_seed(3)
    h = (0.3 * torch.randn(2, 6, 6, generator=g, dtype=torch.float64)).requires_grad_()
    opts = dict(resolution=8, sigma_p_um=1.5, x_um=3.0, y_um=3.0, light=torch.tensor([[0.0, 0.0], [0.2, 0.1]]))
    s = wt.render_slice(h[:, None], **opts)
    assert s.shape == (2, 2, 8, 8, 3) and s.requires_grad
    np.testing.assert_array_equal(s.detach().numpy(),
                                  wb.render_slice(h.detach().numpy()[:, None], **dict(opts, light=opts["light"].numpy())))
    assert torch.autograd.gradcheck(lambda x: wt.render_slice(x[:, None], **opts), (h,), eps=1e-6, atol=1e-6,
                                    rtol=1e-4)
    # 2-D heights under several lights: a batch too, its gradient summed over the lights.
    h2 = h.detach()[0].clone().requires_grad_()
    assert torch.autograd.gradcheck(lambda x: wt.render_slice(x, model="GHS", **opts), (h2,), eps=1e-6, atol=1e-6,
                                    rtol=1e-4)
