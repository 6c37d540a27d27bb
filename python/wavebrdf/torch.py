"""wavebrdf.torch: BRDF slices as a differentiable PyTorch function.

``render_slice(heights, **options)`` takes a 2-D tensor of heights (texel units, float32 or
float64, any device; computed on the CPU) and returns the (n, n, 3) slice as a tensor of the
same dtype and device. Its backward pass is the library's adjoint (wavebrdf.slice_gradient)
on the slice plan its forward built (the forward is not run again): no tape, exact, so heights can sit inside any PyTorch model, loss or optimiser. float64 runs
the library in double precision (use it for torch.autograd.gradcheck), float32 in single.

    import torch, wavebrdf.torch as wt
    h = torch.zeros(16, 16, dtype=torch.float64, requires_grad=True)
    opt = torch.optim.Adam([h], lr=0.01)
    for epoch in range(100):
        opt.zero_grad()
        slice = wt.render_slice(h, resolution=32, sigma_p_um=4, x_um=8, y_um=8, spectral=8)
        loss = ((torch.log1p(slice) - torch.log1p(reference)) ** 2).mean()
        loss.backward()
        opt.step()

Options are those of wavebrdf.render_slice (resolution, texel_um, vscale, x_um, y_um,
sigma_p_um, lambda_um, spectral, light, model); they are not differentiated.

Batches: heights (..., rows, cols), light (2,) or (..., 2) and x_um, y_um as numbers or arrays
(NumPy arrays or tensors) broadcast as in wavebrdf.render_slice; the result is
(batch..., n, n, 3), one slice per item, rendered by one library call threaded across the batch,
and the backward pass is wavebrdf.slice_gradient of the same batch (it renders the batch again:
a batch keeps no plan per item), which sums the gradients of the items that share heights.
The last two axes of heights are one surface: an image-like (rows, cols, channels) tensor is
refused as wavebrdf.render_slice refuses it (pass heights[..., 0]).
"""
import numpy as np
import torch

from . import _core

__all__ = ["RenderSlice", "render_slice"]


def _numpy(tensor, name):
    if not isinstance(tensor, torch.Tensor):
        raise ValueError("%s is a %s; expected a torch.Tensor" % (name, type(tensor).__name__))
    if tensor.layout != torch.strided:
        raise ValueError("%s is a %s tensor; expected a dense (torch.strided) tensor (call .to_dense())"
                         % (name, str(tensor.layout).replace("torch.", "")))
    if tensor.device.type == "meta":
        raise ValueError("%s is on the meta device (shape only, no values); expected a tensor with values "
                         "(cpu, cuda, ...)" % name)
    if tensor.dtype not in (torch.float32, torch.float64):
        raise ValueError("%s has dtype %s; expected torch.float32 or torch.float64" % (name, tensor.dtype))
    # A view of the tensor's memory for CPU tensors (no copy); strides are honoured.
    return tensor.detach().cpu().numpy()


def _plain_options(options):
    """The options with tensors (light, x_um, y_um) as NumPy arrays; they are not differentiated,
    so a tensor that asks for a gradient is refused rather than left with grad None."""
    for name, value in options.items():
        if isinstance(value, torch.Tensor) and value.requires_grad:
            raise ValueError("%s requires grad, but wavebrdf.torch.render_slice differentiates only with respect "
                             "to heights; expected %s.detach() (or a tensor without requires_grad)" % (name, name))
    return {k: (v.detach().cpu().numpy() if isinstance(v, torch.Tensor) else v) for k, v in options.items()}


def _is_single(heights, options):
    """A single query as before batches: 2-D heights, one light pair, scalar positions."""
    return (heights.dim() == 2 and np.ndim(options.get("light", (0.0, 0.0))) <= 1
            and np.ndim(options.get("x_um", 0.0)) == 0 and np.ndim(options.get("y_um", 0.0)) == 0)


class _FirstDerivativeOnly(torch.autograd.Function):
    """Passes a gradient through; differentiating it again (create_graph=True, then a second
    backward or torch.autograd.grad) raises a message that says so."""

    @staticmethod
    def forward(ctx, gradient, *inputs):
        return gradient.clone()

    @staticmethod
    def backward(ctx, *grad_outputs):
        raise RuntimeError("wavebrdf.torch.render_slice: second derivatives (double backward) are not supported; "
                           "the library has the first derivative (the adjoint) only")


class RenderSlice(torch.autograd.Function):
    """heights (..., rows, cols) -> slices (..., n, n, 3); backward by wavebrdf.slice_gradient."""

    @staticmethod
    def forward(ctx, heights, options):
        if heights.dim() < 2:
            raise ValueError("heights has shape %s; expected (rows, cols) or (..., rows, cols)" % (tuple(heights.shape),))
        options = _plain_options(options)
        h = _numpy(heights, "heights")
        ctx.save_for_backward(heights)
        if _is_single(heights, options):
            # One library SlicePlan: its forward now, its adjoint in backward.
            ctx.plan = _core._SlicePlan(h, **options)
            out = ctx.plan.forward()
        else:
            # One batch call (threaded across the batch); backward runs the batch gradient.
            ctx.plan = None
            ctx.options = options
            out = _core.render_slice(h, **options)
        return torch.from_numpy(out).to(heights.device)

    @staticmethod
    def backward(ctx, grad_output):
        (heights,) = ctx.saved_tensors
        weights = _numpy(grad_output, "grad_output")
        if ctx.plan is not None:
            gradient = ctx.plan.adjoint(weights)
        else:
            gradient = _core.slice_gradient(_numpy(heights, "heights"), weights, **ctx.options)
        gradient = torch.from_numpy(np.asarray(gradient)).to(heights.device)
        if torch.is_grad_enabled():  # create_graph=True: a graph whose second backward says why it stops
            gradient = _FirstDerivativeOnly.apply(gradient, grad_output, heights)
        return gradient, None


def render_slice(heights, **options):
    """The BRDF slice of `heights` (a 2-D tensor in texel units) as a differentiable tensor
    (resolution, resolution, 3) of the same dtype and device; with batch axes (heights
    (..., rows, cols), light (..., 2), x_um / y_um arrays, broadcast as wavebrdf.render_slice
    does) the slices (batch..., resolution, resolution, 3). Keyword options as
    wavebrdf.render_slice; `resolution` is required."""
    _numpy(heights, "heights")  # a ValueError naming the argument for what is not a float tensor
    return RenderSlice.apply(heights, options)
