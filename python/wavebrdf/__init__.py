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
lbfgs_minimize) and invert. Heightfield recovery: recover (``wavebrdf recover``; its rarely
used settings in a RecoverSettings), its parts
plan_acquisition, planned_observations, simulate_observations, add_noise, check_acquisition,
recover_heights, recover_heights_thesis, and height_rel_rmse, with_height_range, height_uncertainty
(error bars). ``wavebrdf.torch`` wraps render_slice as a differentiable PyTorch
function. ``python3 -m wavebrdf.report DIR`` (wavebrdf.report) draws the pictures of a
`wavebrdf invert` or `wavebrdf recover` run directory (it needs matplotlib; importing wavebrdf
does not). Bad arguments raise ValueError naming the argument; unreadable files RuntimeError.
"""
from ._core import (  # noqa: F401
    AcquisitionPlan,
    Adam,
    GaborRep,
    Heightfield,
    InversionResult,
    LbfgsResult,
    Loss,
    Observation,
    Query,
    RecoverSettings,
    RecoveryResult,
    add_noise,
    amplitude,
    cie1931_xyz,
    check_acquisition,
    cmsle,
    condition_surface,
    gauss_newton_matrix,
    gradient,
    height_mse,
    height_rel_rmse,
    height_rel_rmse_plane_removed,
    height_uncertainty,
    invert,
    lbfgs_minimize,
    mse,
    observation_loss,
    plan_acquisition,
    planned_observations,
    read_observations,
    recover,
    recover_heights,
    recover_heights_thesis,
    render,
    render_slice,
    rgb_gamma_mse,
    rgb_mse,
    simulate_observations,
    slice_gradient,
    spectral_to_srgb_weights,
    spectral_wavelengths_um,
    surface_acf,
    surface_psd,
    surface_stats,
    with_height_range,
    write_observations,
)

from ._core import __version__  # from the file VERSION, through the extension
from ._core import read_slice  # noqa: F401  (a slice EXR and what it says about itself)
from .table import BrdfTable, lobe_brdf, lobe_table, read_table, render_table  # noqa: F401  (docs/table.md)

__all__ = [
    "AcquisitionPlan", "Adam", "GaborRep", "Heightfield", "InversionResult", "LbfgsResult", "Loss", "Observation",
    "Query", "RecoverSettings", "RecoveryResult", "add_noise", "amplitude", "check_acquisition", "cie1931_xyz", "cmsle", "gauss_newton_matrix", "gradient",
    "height_mse", "height_rel_rmse", "height_rel_rmse_plane_removed", "height_uncertainty", "invert", "lbfgs_minimize", "mse", "observation_loss", "plan_acquisition",
    "planned_observations", "read_observations", "recover", "recover_heights", "recover_heights_thesis", "render",
    "render_slice", "rgb_gamma_mse", "rgb_mse", "simulate_observations", "slice_gradient",
    "spectral_to_srgb_weights", "spectral_wavelengths_um", "with_height_range", "write_observations",
    "BrdfTable", "read_table", "render_table", "lobe_table", "lobe_brdf",
]
__all__ += ["read_slice"]
from ._core import design  # noqa: E402,F401  (docs/design.md)
__all__ += ["design"]
from ._core import design_plate  # noqa: E402,F401  (docs/design.md, "Plate")
__all__ += ["design_plate"]
__all__ += ["condition_surface", "surface_acf", "surface_psd", "surface_stats"]
# What the recovery's planner reads from a known surface (docs/recovery.md, "Rough surfaces").
from ._core import measure_roughness  # noqa: E402,F401
__all__ += ["measure_roughness"]
# Observation files that scale (HDF5, docs/observations_hdf5.md): what a file holds without its slices.
from ._core import built_with_hdf5, read_observation_index  # noqa: F401
__all__ += ["built_with_hdf5", "read_observation_index"]
# Files for fabricating a relief: 16-bit heights PNG, lithography masks, STL (docs/fabrication.md).
from ._core import write_fabrication_exports  # noqa: F401
__all__ += ["write_fabrication_exports"]
# Camera pictures of the surface (docs/image.md).
from ._core import image_gradient, render_image  # noqa: F401
__all__ += ["image_gradient", "render_image"]
# A call with a missing or misspelt keyword names it (pybind11 alone lists every signature).
from ._arguments import explained as _explained  # noqa: E402

for _name in ("render_slice", "slice_gradient", "render", "gradient", "observation_loss", "invert", "recover",
              "recover_heights", "recover_heights_thesis", "plan_acquisition", "planned_observations",
              "simulate_observations", "height_uncertainty", "gauss_newton_matrix", "height_rel_rmse", "height_rel_rmse_plane_removed",
              "read_observations", "write_observations", "render_image", "image_gradient", "design",
              "design_plate", "surface_stats", "condition_surface", "write_fabrication_exports",
              "measure_roughness"):
    globals()[_name] = _explained(globals()[_name])
del _name
