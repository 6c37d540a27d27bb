"""wavebrdf: wave-optical BRDFs of microscale heightfields (Yan et al. 2018), their gradients
with respect to the heights, and the inverse renderer, from Python.

Lengths are in micrometres (``_um``); heights are in units of the texel width (height in um =
vscale * texel_um * value). Slices are NumPy arrays of shape (n, n, 3), linear RGB, pixel
(i, j) at the projected outgoing direction ((i + 1/2) / n * 2 - 1, (j + 1/2) / n * 2 - 1).

Two plain functions carry everything else:

    render_slice(heights, *, resolution, texel_um, vscale, x_um, y_um, sigma_p_um,
                 lambda_um=None, spectral=None, light=(0, 0), model="OHS")  -> (n, n, 3)
    slice_gradient(heights, weights, *, the same)  -> d sum(weights * slice) / d heights

and the objects of the thesis's listing 4.1: Heightfield, GaborRep, Query, render, the losses
(Loss, cmsle, mse, amplitude), gradient / observation_loss, the optimisers (Adam,
lbfgs_minimize) and invert. ``wavebrdf.torch`` wraps render_slice as a differentiable PyTorch
function. Bad arguments raise ValueError naming the argument; unreadable files RuntimeError.
"""
from ._core import (  # noqa: F401
    Adam,
    GaborRep,
    Heightfield,
    InversionResult,
    LbfgsResult,
    Loss,
    Observation,
    Query,
    amplitude,
    cie1931_xyz,
    cmsle,
    gradient,
    height_mse,
    invert,
    lbfgs_minimize,
    mse,
    observation_loss,
    read_observations,
    render,
    render_slice,
    rgb_gamma_mse,
    rgb_mse,
    slice_gradient,
    spectral_to_srgb_weights,
    spectral_wavelengths_um,
    write_observations,
)

__version__ = "0.1.0"

__all__ = [
    "Adam", "GaborRep", "Heightfield", "InversionResult", "LbfgsResult", "Loss", "Observation", "Query",
    "amplitude", "cie1931_xyz", "cmsle", "gradient", "height_mse", "invert", "lbfgs_minimize", "mse",
    "observation_loss", "read_observations", "render", "render_slice", "rgb_gamma_mse", "rgb_mse",
    "slice_gradient", "spectral_to_srgb_weights", "spectral_wavelengths_um", "write_observations",
]
