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
"""
import numpy as np
import torch
from torch.autograd.function import once_differentiable

from . import _core

__all__ = ["RenderSlice", "render_slice"]


def _numpy(tensor, name):
    if not isinstance(tensor, torch.Tensor):
        raise ValueError("%s is a %s; expected a torch.Tensor" % (name, type(tensor).__name__))
    if tensor.dtype not in (torch.float32, torch.float64):
        raise ValueError("%s has dtype %s; expected torch.float32 or torch.float64" % (name, tensor.dtype))
    # A view of the tensor's memory for CPU tensors (no copy); strides are honoured.
    return tensor.detach().cpu().numpy()


class RenderSlice(torch.autograd.Function):
    """heights (rows, cols) -> slice (n, n, 3); backward by wavebrdf.slice_gradient."""

    @staticmethod
    def forward(ctx, heights, options):
        if heights.dim() != 2:
            raise ValueError("heights has shape %s; expected (rows, cols)" % (tuple(heights.shape),))
        # One library SlicePlan: its forward now, its adjoint in backward.
        plan = _core._SlicePlan(_numpy(heights, "heights"), **options)
        out = plan.forward()
        ctx.plan = plan
        ctx.save_for_backward(heights)
        return torch.from_numpy(out).to(heights.device)

    @staticmethod
    @once_differentiable
    def backward(ctx, grad_output):
        (heights,) = ctx.saved_tensors
        weights = _numpy(grad_output, "grad_output")
        gradient = ctx.plan.adjoint(weights)
        return torch.from_numpy(np.asarray(gradient)).to(heights.device), None


def render_slice(heights, **options):
    """The BRDF slice of `heights` (a 2-D tensor in texel units) as a differentiable tensor
    (resolution, resolution, 3) of the same dtype and device. Keyword options as
    wavebrdf.render_slice; `resolution` is required."""
    _numpy(heights, "heights")  # a ValueError naming the argument for what is not a float tensor
    return RenderSlice.apply(heights, options)
