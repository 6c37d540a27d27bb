"""wavebrdf.torch: the slice as a torch.autograd.Function with the library's adjoint as backward."""
import numpy as np
import pytest

torch = pytest.importorskip("torch", reason="python3-torch is installed by scripts/setup.sh")
import wavebrdf as wb  # noqa: E402
import wavebrdf.torch as wt  # noqa: E402

SMALL = dict(resolution=8, sigma_p_um=1.5, x_um=3.0, y_um=3.0)


def small_heights(seed=0, dtype=torch.float64):
    g = torch.Generator().manual_seed(seed)
    return (0.4 * torch.randn(6, 6, generator=g, dtype=dtype)).requires_grad_()


@pytest.mark.parametrize("opts", [
    SMALL,
    dict(SMALL, model="GHS", light=(0.2, 0.1), spectral=3, texel_um=0.9, vscale=1.2),
    dict(SMALL, model="Kirchhoff", lambda_um=0.6, x_um=0.5),
], ids=["OHS-mono", "GHS-spectral", "Kirchhoff"])
def test_gradcheck_double(opts):
    h = small_heights()
    assert torch.autograd.gradcheck(lambda x: wt.render_slice(x, **opts), (h,), eps=1e-6, atol=1e-6, rtol=1e-4)


def test_gradcheck_detects_a_wrong_backward():
    # The check above must be able to fail: the same function with its gradient scaled by 1.01.
    class Wrong(wt.RenderSlice):
        @staticmethod
        def backward(ctx, grad_output):
            g, _ = wt.RenderSlice.backward(ctx, grad_output)
            return 1.01 * g, None

    h = small_heights()
    assert not torch.autograd.gradcheck(lambda x: Wrong.apply(x, SMALL), (h,), eps=1e-6, atol=1e-6, rtol=1e-4,
                                        raise_exception=False)


def test_forward_and_backward_are_the_numpy_functions():
    for dtype, np_dtype in ((torch.float64, np.float64), (torch.float32, np.float32)):
        h = small_heights(1, dtype)
        s = wt.render_slice(h, spectral=4, **SMALL)
        assert s.dtype == dtype and s.shape == (8, 8, 3) and s.requires_grad
        expected = wb.render_slice(h.detach().numpy(), spectral=4, **SMALL)
        assert expected.dtype == np_dtype
        np.testing.assert_array_equal(s.detach().numpy(), expected)
        w = torch.linspace(-1, 1, 8 * 8 * 3, dtype=dtype).reshape(8, 8, 3)
        (s * w).sum().backward()
        g = wb.slice_gradient(h.detach().numpy(), w.numpy(), spectral=4, **SMALL)
        assert h.grad.dtype == dtype
        np.testing.assert_array_equal(h.grad.numpy(), g)


def test_inside_a_torch_optimiser():
    # The thesis's first experiment with torch.optim.Adam and a CMSLE written in torch: from a flat
    # start the loss falls (the library's own loop reaches about 25 % of epoch 0 by epoch 50).
    truth = torch.from_numpy(wb.Heightfield.generate("isotropic", rows=16, rms_height_um=0.35, correlation_um=2.0,
                                                     seed=1).to_numpy())
    opts = dict(resolution=32, sigma_p_um=4.0, x_um=8.0, y_um=8.0, spectral=8)
    reference = wt.render_slice(truth, **opts)
    h = torch.zeros(16, 16, dtype=torch.float64, requires_grad=True)
    opt = torch.optim.Adam([h], lr=0.01, betas=(0.9, 0.99))
    losses = []
    for _ in range(60):
        opt.zero_grad()
        slice_ = wt.render_slice(h, **opts)
        loss = ((torch.log(slice_.clamp(min=0) + 1) - torch.log(reference + 1)) ** 2).sum(dim=-1).mean()
        loss.backward()
        opt.step()
        losses.append(loss.item())
    assert losses[-1] < 0.5 * losses[0]


def test_non_contiguous_tensor_and_expanded_gradient():
    h = small_heights(3)
    ht = h.detach().t().contiguous().t().requires_grad_()  # column-major storage
    a = wt.render_slice(h, **SMALL)
    b = wt.render_slice(ht, **SMALL)
    assert torch.equal(a, b)
    b.sum().backward()  # grad_output is an expanded tensor (stride 0)
    g = wb.slice_gradient(h.detach().numpy(), np.ones((8, 8, 3)), **SMALL)
    np.testing.assert_allclose(ht.grad.numpy(), g, rtol=1e-12, atol=0)


def test_errors():
    # (3, 3, 3) is a batch of three (tests/python/test_batch.py); 1-D is refused.
    with pytest.raises(ValueError, match="heights has shape"):
        wt.render_slice(torch.zeros(3, dtype=torch.float64), **SMALL)
    with pytest.raises(ValueError, match="dtype"):
        wt.render_slice(torch.zeros(3, 3, dtype=torch.int64), **SMALL)
    with pytest.raises(ValueError, match="sigma_p_um"):
        wt.render_slice(torch.zeros(3, 3, dtype=torch.float64), **dict(SMALL, sigma_p_um=0))


def test_numpy_array_is_a_value_error_naming_the_argument():
    # It used to be AttributeError ('numpy.ndarray' object has no attribute 'dim').
    with pytest.raises(ValueError, match="heights is a ndarray; expected a torch.Tensor"):
        wt.render_slice(np.zeros((3, 3)), **SMALL)
    with pytest.raises(ValueError, match="heights is a list"):
        wt.render_slice([[0.0, 1.0], [1.0, 0.0]], **SMALL)
