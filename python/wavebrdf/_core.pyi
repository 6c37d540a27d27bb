"""Type stubs of wavebrdf._core, written by scripts/gen_stubs.py from the module's signatures and
docstrings (run it again after changing a binding; tests/python/test_stubs.py checks them)."""
from typing import Any, Callable, Dict, Iterable, Iterator, List, Optional, Sequence, Set, Tuple, Union, overload

import os

import numpy

__version__: str

class AcquisitionPlan:
    """What plan_acquisition proposes: footprint centres on a jittered raster over the periodic tile,
    a slice resolution that samples the window (within 4x of Nyquist, at least 48), and wavelengths whose synthetic
    wavelengths unwrap the height range. planned_observations / simulate_observations turn it
    into Observations (one per position, light and wavelength).
    """
    @property
    def sigma_p_um(self) -> float:
        """footprint sigma_p, um"""
        ...
    @property
    def resolution(self) -> int:
        """slice pixels per side"""
        ...
    @property
    def lambdas_um(self) -> List[float]:
        """wavelengths in um, lambda0 first"""
        ...
    @property
    def synthetic_um(self) -> List[float]:
        """the synthetic wavelengths lambda_a lambda_b / |lambda_a - lambda_b| in um, coarsest first"""
        ...
    @property
    def positions_um(self) -> numpy.ndarray:
        """footprint centres (x_um, y_um), a float64 array (N, 2) (a copy)"""
        ...
    @property
    def step_um(self) -> tuple:
        """raster steps (x, y) in um"""
        ...
    @property
    def overlap(self) -> float:
        """worst-case linear overlap 1 - d/D of neighbouring windows (D = 6 sigma_p), jitter included"""
        ...
    @property
    def light(self) -> tuple:
        """projected light direction (wx, wy) (of every observation without oblique_lights)"""
        ...
    @property
    def oblique_lights(self) -> list:
        """further light directions (wx, wy) under which every position is observed as well (steep surfaces; empty: one light)"""
        ...
    @property
    def model(self) -> str:
        ...
    @property
    def notes(self) -> List[str]:
        """the choices, one line each"""
        ...
    def __repr__(self) -> str:
        ...

class Adam:
    """Adam (Kingma and Ba 2015) with an exponential learning-rate decay per epoch:
    lr_epoch = lr * exp(-decay * epoch). Defaults are the thesis's.

    Adam(size, lr=0.01, beta1=0.9, beta2=0.99, epsilon=1e-8, decay=0.005)
        size    number of parameters (e.g. rows * cols heights), >= 1
        lr > 0; beta1, beta2 in [0, 1); epsilon > 0; decay >= 0 (per epoch)
    """
    def __init__(self, size: int, lr: float = ..., beta1: float = ..., beta2: float = ..., epsilon: float = ..., decay: float = ...) -> None:
        ...
    def step(self, x: Any, gradient: Any, epoch: int = ...) -> numpy.ndarray:
        """One update of x (a writable C-contiguous float64 array of `size` values, any shape, changed in
        place and returned) against `gradient` (same number of finite values), at the learning rate
        of `epoch` (0-based).
        """
        ...
    def learning_rate(self, epoch: int) -> float:
        """lr * exp(-decay * epoch)"""
        ...
    @property
    def size(self) -> int:
        ...
    @property
    def steps(self) -> int:
        """steps taken (bias correction)"""
        ...
    @property
    def m(self) -> numpy.ndarray:
        """first moment (a copy)"""
        ...
    @property
    def v(self) -> numpy.ndarray:
        """second moment (a copy)"""
        ...
    def set_state(self, m: Any, v: Any, steps: int) -> None:
        """Restores moments and step count (e.g. from a checkpoint)."""
        ...

class GaborRep:
    """The Gabor kernels of a heightfield that fall within 3 sigma_p of a footprint centre (the
    model's cut; docs/model.md §3-4), independent of wavelength and directions: one kernel
    per texel, at its nearest periodic image. Arrays are read-only float64 views (kernel order):

        row, col        texel (i, j) of each kernel (int32)
        dx_um, dy_um    kernel centre minus footprint centre, um
        weight          footprint window weight times kernel area c_k w^2, um
        height_um       kernel height H_k = vscale * texel_um * h[i, j], um
        slope_x/_y      dimensionless slope s_k (periodic central differences of h, times vscale)

    GaborRep(heightfield, query)  or
    GaborRep(heightfield, x_um=None, y_um=None, sigma_p_um=10.0)
        x_um, y_um default to the tile centre; sigma_p_um > 0 in um.

    The inverse transform ``to_heights`` / ``to_heightfield`` recovers heightfield values from
    kernel heights (h = H / (vscale * texel_um)); slopes follow from the heights and are not
    independent parameters, so they are not used.
    """
    @overload
    def __init__(self, heightfield: Heightfield, query: Query) -> None:
        ...
    @overload
    def __init__(self, heightfield: Heightfield, x_um: Any = ..., y_um: Any = ..., sigma_p_um: float = ...) -> None:
        ...
    def __len__(self) -> int:
        ...
    @property
    def size(self) -> int:
        """number of kernels"""
        ...
    @property
    def x_um(self) -> float:
        """footprint centre along x, um"""
        ...
    @property
    def y_um(self) -> float:
        """footprint centre along y, um"""
        ...
    @property
    def sigma_p_um(self) -> float:
        """footprint sigma_p, um"""
        ...
    @property
    def sigma_um(self) -> float:
        """kernel sigma = texel_um / 2, um"""
        ...
    @property
    def shape(self) -> tuple:
        """(rows, cols) of the heightfield"""
        ...
    @property
    def texel_um(self) -> float:
        ...
    @property
    def vscale(self) -> float:
        ...
    @property
    def row(self) -> numpy.ndarray:
        ...
    @property
    def col(self) -> numpy.ndarray:
        ...
    @property
    def dx_um(self) -> numpy.ndarray:
        ...
    @property
    def dy_um(self) -> numpy.ndarray:
        ...
    @property
    def weight(self) -> numpy.ndarray:
        ...
    @property
    def height_um(self) -> numpy.ndarray:
        ...
    @property
    def slope_x(self) -> numpy.ndarray:
        ...
    @property
    def slope_y(self) -> numpy.ndarray:
        ...
    @property
    def positions_um(self) -> numpy.ndarray:
        """(size, 2) kernel centres mu_k = footprint centre + (dx_um, dy_um), um (a new array)"""
        ...
    @property
    def covered(self) -> numpy.ndarray:
        """(rows, cols) bool mask of the texels that have a kernel"""
        ...
    def to_heights(self, height_um: Any = ..., fill: float = ...) -> numpy.ndarray:
        """The inverse transform: heightfield values in texel units, h = H_k / (vscale * texel_um), at
        each kernel's texel; ``fill`` (default NaN) where no kernel lies. ``height_um`` (length
        ``size``, um) replaces the kernel heights; default: this representation's own.
        """
        ...
    def to_heightfield(self, height_um: Any = ..., base: Heightfield = ...) -> Heightfield:
        """The inverse transform as a Heightfield (same texel_um and vscale): kernel heights (this
        representation's, or ``height_um``) at the covered texels, ``base``'s values elsewhere
        (required unless every texel is covered).
        """
        ...
    def __repr__(self) -> str:
        ...

class Heightfield:
    """A periodic heightfield on a grid of square texels (the public release's convention).

    Values are heights in units of the texel width: the height in um is
    ``vscale * texel_um * value``. Row index i runs along the surface coordinate x, column j
    along y; the surface tiles the plane.

    Heightfield(values, texel_um=1.0, vscale=1.0)
        values    2-D float32/float64 array (rows, cols) of finite heights in texel units
                  (copied once into the heightfield, as float64)
        texel_um  texel width w in um, finite and > 0
        vscale    vertical scale v (dimensionless), finite
    """
    def __init__(self, values: Any, texel_um: float = ..., vscale: float = ...) -> None:
        ...
    @staticmethod
    def from_exr(path: Union[str, os.PathLike], texel_um: Any = ..., vscale: Any = ...) -> Heightfield:
        """Reads the R (or Y) channel of an OpenEXR file (half or float) as heights in texel units.
        texel_um (um) and vscale: when None (default), the file's own (written by save_exr and the
        CLI), else 1.0; a given value that differs from the file's wins, with a UserWarning naming
        both. RuntimeError names the file when it is missing, unreadable or corrupt, or has a
        hostile wavebrdf attribute; ValueError on a non-finite value.
        """
        ...
    @staticmethod
    def read(path: Union[str, os.PathLike], texel_um: Any = ..., vscale: Any = ...) -> Heightfield:
        """Reads a heightfield EXR or a measured surface (x3p, sdf, Zygo .dat and .datx, sur, plu, al3d, npy,
        text matrix; recognised by content, docs/surfaces.md). A measured surface keeps its heights
        in um and is transposed so that row index i runs along x; its spacing must be square and every
        point measured (else ValueError: run `wavebrdf convert` with --resample-um / --fill). texel_um:
        the file's spacing when None; npy and text files state none and need it. vscale: 1 when None.
        """
        ...
    @staticmethod
    def exr_attributes(path: Union[str, os.PathLike]) -> dict:
        """What a heightfield EXR says about itself (no pixels read): a dict with texel_um, vscale
        (None when the file does not say), units, made_by and version ('' when absent).
        """
        ...
    @property
    def rows(self) -> int:
        ...
    @property
    def cols(self) -> int:
        ...
    @property
    def shape(self) -> tuple:
        """(rows, cols)"""
        ...
    @property
    def texel_um(self) -> float:
        """texel width w in um"""
        ...
    @property
    def vscale(self) -> float:
        """vertical scale v"""
        ...
    @property
    def period_x_um(self) -> float:
        """tile period along x (rows), um"""
        ...
    @property
    def period_y_um(self) -> float:
        """tile period along y (columns), um"""
        ...
    @property
    def values(self) -> numpy.ndarray:
        """The heights in texel units, a read-only float64 view (rows, cols) of this heightfield's
        memory (no copy). Assigning an array of the same shape overwrites them in place.
        """
        ...
    @values.setter
    def values(self, value: numpy.ndarray) -> None: ...
    def to_numpy(self) -> numpy.ndarray:
        """A writable float64 copy of the values (rows, cols), in texel units."""
        ...
    def __array__(self, dtype: Any = ...) -> numpy.ndarray:
        ...
    def heights_um(self) -> numpy.ndarray:
        """Heights in um, vscale * texel_um * values (a new float64 array)."""
        ...
    def slope(self, i: int, j: int) -> tuple:
        """Dimensionless slope (s_x, s_y) at texel (i, j) by periodic central differences."""
        ...
    def with_values(self, values: Any) -> Heightfield:
        """The same geometry with other values (same shape)."""
        ...
    def with_scale(self, texel_um: float, vscale: float) -> Heightfield:
        """The same values with another texel width (um) and vertical scale."""
        ...
    def save_exr(self, path: Union[str, os.PathLike], made_by: str = ...) -> None:
        """Writes the values (texel units) as a single-channel float EXR (atomically), with the
        attributes texel_um, vscale, units, made_by and the wavebrdf version (docs/conventions.md,
        "Files"), so that from_exr reads the same scale back. ValueError for a path not ending in .exr.
        """
        ...
    def save(self, path: Union[str, os.PathLike], made_by: str = ...) -> None:
        """Writes the heightfield in the format of path's extension: .exr (save_exr), .x3p, .sdf or .npy
        (heights in um, transposed to rows along y as those formats store them; docs/surfaces.md).
        ValueError for another extension.
        """
        ...
    def save_png(self, path: Union[str, os.PathLike]) -> None:
        """Writes a grey PNG preview, min black, max white. ValueError for a path not ending in .png."""
        ...
    def copy(self) -> Heightfield:
        ...
    def __copy__(self) -> Heightfield:
        ...
    def __deepcopy__(self, memo: dict) -> Heightfield:
        ...
    def __repr__(self) -> str:
        ...
    @staticmethod
    def generate(type: str = ..., rows: int = ..., cols: Optional[int] = ..., texel_um: float = ..., seed: int = ..., rms_height_um: float = ..., rms_slope: float = ..., correlation_um: float = ..., anisotropy: float = ..., scratch_count: int = ..., scratch_depth_um: float = ..., scratch_width_um: float = ..., amplitude_um: float = ..., period_um: float = ...) -> Heightfield:
        """A procedural periodic surface, deterministic in ``seed`` (as ``wavebrdf heightfield``).

        type  'flat', 'isotropic' (Gaussian-correlated noise with rms height rms_height_um, or rms
              slope rms_slope when > 0, correlation length correlation_um), 'brushed' (the same,
              anisotropy times longer along y), 'scratched' (scratch_count Gaussian grooves of depth
              scratch_depth_um and width scratch_width_um on a smooth base) or 'grating'
              (amplitude_um * sin(2 pi x / period_um)). Lengths in um; rows, cols in 1...16384
              (cols defaults to rows). The result has vscale 1 and texel width texel_um.
        """
        ...
    def stats(self) -> dict:
        """Mean, rms height, min and max in um (vscale included) and rms slope."""
        ...
    @staticmethod
    def from_um(heights_um: Any, texel_um: float, vscale: float = ...) -> Heightfield:
        """A Heightfield from heights in um (2-D, finite; axis 0 along x as Heightfield(values)) on square
        texels of texel_um: values heights_um / (vscale * texel_um). For NaN or non-square spacing,
        wavebrdf.condition_surface first.
        """
        ...
    def conditioned(self, detrend: str = ..., crop: Any = ..., resample_um: Any = ..., periodic: str = ...) -> Heightfield:
        """This heightfield conditioned (as `wavebrdf convert`; crop indices are (i0, j0, rows, cols) of
        this heightfield), in order: crop, detrend ('none', 'mean', 'plane', 'poly:N'), resample_um
        (bilinear) and periodic ('none', 'smooth', 'mirror'). Heights in um are kept; the vertical scale
        is kept (1 for a flat vscale 0).
        """
        ...

class InversionResult:
    """What invert() returns."""
    @property
    def estimate(self) -> Any:
        """the recovered Heightfield"""
        ...
    @property
    def truth(self) -> Any:
        """the truth Heightfield (None with observations)"""
        ...
    @property
    def observations(self) -> Any:
        """the Observations fitted"""
        ...
    @property
    def metrics(self) -> Any:
        """dict of float64 arrays, one entry per evaluated epoch (the CLI's metrics.csv columns): epoch,
        loss, brdf_mse, cmsle_1, cmsle_0.001, rgb_mse, rgb_gamma_mse, height_mse (um^2 after removing
        the mean; NaN without a truth), seconds.
        """
        ...
    @property
    def final_slices(self) -> Any:
        """the observations' slices rendered from the estimate, shaped like their references"""
        ...
    @property
    def epochs(self) -> int:
        """the last epoch reached"""
        ...
    @property
    def stopped(self) -> bool:
        """True when the callback stopped the run early"""
        ...

class LbfgsResult:
    """The outcome of lbfgs_minimize."""
    @property
    def iterations(self) -> int:
        """accepted steps"""
        ...
    @property
    def evaluations(self) -> int:
        """objective calls, the first included"""
        ...
    @property
    def value(self) -> float:
        """objective at the returned x"""
        ...
    @property
    def converged(self) -> bool:
        """max |gradient| <= gradient_tolerance"""
        ...
    def __repr__(self) -> str:
        ...

class Loss:
    """A loss between an estimated and a reference slice (the thesis's Definition 3.2):
        'cmsle:EPS'  1/|P| sum_p sum_c (log(I + EPS) - log(R + EPS))^2, EPS > 0 ('cmsle' = 'cmsle:1')
        'mse'        1/|P| sum_p sum_c (I - R)^2
        'amplitude'  1/|P| sum_p sum_c (sqrt(I) - sqrt(R))^2
        'poisson:N'  1/|P| sum_p sum_c 2 (k log(k / mu) - (k - mu)), k = s R, mu = s I, s = N / sum(R):
                     the Poisson deviance of a slice measured with N photons (N > 0)
    Negative values are clamped to 0 for the log and square root (and get gradient 0).
    Loss(spec='cmsle:1'); loss(estimate, reference) -> float;
    loss.value_and_gradient(estimate, reference) -> (float, dloss/destimate shaped like estimate).
    estimate, reference: float arrays of the same shape, finite; an (n, n, c) array has c
    channels per pixel, any other shape one. The loss is a mean over pixels of a sum over channels.
    """
    def __init__(self, spec: str = ...) -> None:
        ...
    @property
    def kind(self) -> str:
        """'cmsle', 'mse', 'amplitude' or 'poisson'"""
        ...
    @property
    def epsilon(self) -> float:
        """CMSLE's epsilon"""
        ...
    @property
    def photons(self) -> float:
        """Poisson's photons per slice N"""
        ...
    def __call__(self, estimate: Any, reference: Any) -> float:
        ...
    def value_and_gradient(self, estimate: Any, reference: Any) -> tuple:
        ...
    def __str__(self) -> str:
        ...
    def __repr__(self) -> str:
        ...

class Observation:
    """A reference slice with the query that produced it (an input of observation_loss and invert).

    Observation(query, reference, weights=None)
        query      a Query
        reference  the slice, finite: (n, n) for one wavelength, (n, n, 3) linear sRGB for a
                   spectral query (may be slightly negative: out-of-gamut colours); n = the
                   resolution (1...8192); stored rounded to float32
        weights    None (every pixel weighs 1) or (n, n) per-pixel weights, finite, >= 0, not all 0:
                   the loss is the weighted mean over pixels, so a pixel of weight 0 (dead,
                   saturated, unmeasured) changes neither the loss nor its gradient, and its
                   reference value may be anything, NaN included; stored as float32
    """
    def __init__(self, query: Query, reference: Any, weights: Any = ...) -> None:
        ...
    @staticmethod
    def from_slice(path: Union[str, os.PathLike], weights: Any = ...) -> Observation:
        """The observation of a slice EXR written by wavebrdf (render --out, genbrdf -o, a run's
        reference_ slices): its query and wavelengths from the file's attributes, as `wavebrdf
        invert --reference` reads it; weights as the constructor's. ValueError for a file
        without the attributes (a measured slice: use Observation(query, reference)).
        """
        ...
    @property
    def weights(self) -> Any:
        """the per-pixel weights, a read-only float32 (n, n) view, or None (every pixel weighs 1)"""
        ...
    @property
    def query(self) -> Query:
        ...
    @property
    def resolution(self) -> int:
        ...
    @property
    def channels(self) -> int:
        """1 (one wavelength) or 3 (RGB)"""
        ...
    @property
    def lambdas_um(self) -> List[float]:
        ...
    @property
    def reference(self) -> numpy.ndarray:
        """the reference slice, a read-only float32 view (stored in float, as in the slice files)"""
        ...
    def render(self, heightfield: Heightfield, *, path: str = ..., tolerance: float = ...) -> numpy.ndarray:
        """What this observation would see of `heightfield`, shaped like the reference (float64); path and
        tolerance as wavebrdf.render_slice's.
        """
        ...
    def __repr__(self) -> str:
        ...

class Query:
    """One BRDF query: a Gaussian footprint on the surface, a light direction, a diffraction model
    and the wavelength(s).

    Query(x_um=0.0, y_um=0.0, sigma_p_um=10.0, light=(0.0, 0.0), model='OHS', lambda_um=None,
          spectral=None)
        x_um, y_um   footprint centre in um (x along rows, y along columns); finite, periodic
        sigma_p_um   footprint standard deviation in um, 1e-6 to 1e6 (and <= 10 tile periods)
        light        projected direction towards the light (wx, wy), wx^2 + wy^2 < 1
        model        'OHS', 'GHS', 'ROHS', 'RGHS' or 'Kirchhoff'
        lambda_um    one wavelength in um (0.01 to 1000); default 0.5 when spectral is None
        spectral     N samples over 0.36-0.83 um (1...256) or a list of wavelengths in um, to
                     linear sRGB (CIE 1931); excludes lambda_um
    Position, sigma_p, light and model can be set later (validated); the wavelengths are fixed.
    """
    def __init__(self, x_um: float = ..., y_um: float = ..., sigma_p_um: float = ..., light: Any = ..., model: str = ..., lambda_um: Any = ..., spectral: Any = ...) -> None:
        ...
    @property
    def x_um(self) -> float:
        ...
    @x_um.setter
    def x_um(self, value: float) -> None: ...
    @property
    def y_um(self) -> float:
        ...
    @y_um.setter
    def y_um(self, value: float) -> None: ...
    @property
    def sigma_p_um(self) -> float:
        ...
    @sigma_p_um.setter
    def sigma_p_um(self, value: float) -> None: ...
    @property
    def light(self) -> tuple:
        ...
    @light.setter
    def light(self, value: tuple) -> None: ...
    @property
    def model(self) -> str:
        ...
    @model.setter
    def model(self, value: str) -> None: ...
    @property
    def lambdas_um(self) -> List[float]:
        """the wavelengths in um"""
        ...
    @property
    def spectral(self) -> bool:
        """True when the slice is spectral (RGB through CIE 1931)"""
        ...
    def kwargs(self) -> dict:
        """The query as keyword arguments of render_slice and slice_gradient."""
        ...
    def copy(self) -> Query:
        ...
    def __copy__(self) -> Query:
        ...
    def __deepcopy__(self, memo: dict) -> Query:
        ...
    def __repr__(self) -> str:
        ...

class RecoverSettings:
    """The recovery's rarely used settings, for recover(settings=...) and recover_heights(settings=...):
    the CLI's options of the same names (docs/recovery.md, "Settings by stage") and recover_heights'
    stages' own; None: the library's (the schedule's). The functions convert them and the library
    checks them, naming them as here. recover() refuses the stages' own (below, last) and
    recover_heights the acquisition's (overlap, jitter, oblique_lights, plan_from_truth, simulator,
    simulate_*, epochs) when set. Each is an attribute of the same name.

    field_iterations, refine_iterations  pipeline iterations (>= 0; None: the schedule's)
    field_tile_threshold, field_tile_core  the field stage on tiles (the CLI's --field-tile-threshold /
                  --field-tile-core): a surface with a side above the threshold (texels, 0...10^6; 0:
                  never) is retrieved on tiles of about `field_tile_core` texels (8...4096) plus a
                  margin; None: the library's (64, 48)
    refine_coarse_spacing, refine_coarse_weight, refine_coarse_iterations  the refinement's coarse
                  space (the CLI's --refine-coarse-*): node spacing in texels (0: off), the joint
                  variables' weight, coarse-only iterations per round; None: the library's
    position_passes  with calibrate 'positions' (or 'all'): at most this many passes of the
                  position loop after the first recovery (the CLI's --position-passes, 0...100; 0:
                  off; None: the library's, 40, stopped earlier when the loss stalls); its per-pass
                  steps are in result.metrics (positions:register, positions:newton, ...)
    white_smoothness  white light's smoothness continuation (the CLI's --white-smoothness): weights,
                  largest first (at most 64, each 0 ... 1e12; [] none; None: the library's 10, 1,
                  0.1, 0.01); white_smoothness_iterations: L-BFGS iterations per weight (None: 20)
    epochs        method 'thesis': Adam epochs (>= 0, default 1000)
    overlap       the planner's worst-case overlap of neighbouring windows, 0.6 ... 0.95 (None: 0.6,
                  0.8 with calibrate 'positions' or 'all'); jitter 0 ... 0.3 (default 0.2)
    oblique_lights  steep generated surfaces (expected rms slope > 0.2 from height_range_um and
                  correlation_texels): every position is observed under 4 oblique lights at
                  sin(theta_i) = 0.8 as well, so that steep facets reflect into a slice (default
                  True; OHS and ROHS: GHS-type models keep one light); False: under `light` alone
                  (the CLI's --no-oblique-lights)
    plan_from_truth  None (default): as the CLI, a given truth is planned for its measured
                  roughness (measure_roughness: peak to valley, rms slope, Sal, Str; a rough, steep
                  or strongly striated surface gets long wavelengths, oblique lights and the longer
                  schedule, docs/recovery.md "Rough surfaces") unless correlation_texels is given;
                  True: that (a truth needed, not with correlation_texels); False: the stated plan
                  (height range and correlation_texels, default 4)
    simulator     how a truth's observations are simulated: 'gabor' (the model, default) or
                  'scalar' (the exact field of the interpolated heights, scalar_diffraction.h;
                  OHS / ROHS); not with observations
    simulate_position_error_texels, simulate_exposure, simulate_sigma_factor  a study's
                  acquisition errors (the CLI's --simulate-*; a truth only): footprint positions off
                  by this rms per coordinate (texels, 0...10), each slice scaled by an exposure
                  log-uniform in (min, max), the true sigma_p this factor times the stated one
                  (0.25...4); the recovery is given the stated acquisition
    The stages' own (recover_heights only; None: RecoverSettings' defaults, recover.h):
    blur_widths   blurred fit: blur widths in footprint lobes, widest first ([]: start the fields
                  from flat); blur_iterations: L-BFGS per width (>= 0)
    blur_wavelengths  the blurred fit uses this many longest wavelengths (0: all), at positions at
                  least 2 sigma_p apart
    band_limit    the field stage keeps only the object's spectrum the slices see
    refine        odd object-grid refinement 1...63 (0: automatic)
    max_range_um  bound on the height range for unwrapping (um, > 0; None: 4)
    refine_history  L-BFGS history of the refinement (>= 1); refine_loss: 'amplitude', 'poisson:N',
                  'mse', 'cmsle:EPS' or a Loss
    """
    def __init__(self, *, field_iterations: Any = ..., refine_iterations: Any = ..., field_tile_threshold: Any = ..., field_tile_core: Any = ..., refine_coarse_spacing: Any = ..., refine_coarse_weight: Any = ..., refine_coarse_iterations: Any = ..., position_passes: Any = ..., white_smoothness: Any = ..., white_smoothness_iterations: Any = ..., epochs: Any = ..., overlap: Any = ..., jitter: Any = ..., oblique_lights: Any = ..., plan_from_truth: Any = ..., simulator: Any = ..., simulate_position_error_texels: Any = ..., simulate_exposure: Any = ..., simulate_sigma_factor: Any = ..., blur_widths: Any = ..., blur_iterations: Any = ..., blur_wavelengths: Any = ..., band_limit: Any = ..., refine: Any = ..., max_range_um: Any = ..., refine_history: Any = ..., refine_loss: Any = ...) -> None:
        ...
    def __repr__(self) -> str:
        ...
    @property
    def field_iterations(self) -> Any:
        ...
    @field_iterations.setter
    def field_iterations(self, value: Any) -> None: ...
    @property
    def refine_iterations(self) -> Any:
        ...
    @refine_iterations.setter
    def refine_iterations(self, value: Any) -> None: ...
    @property
    def field_tile_threshold(self) -> Any:
        ...
    @field_tile_threshold.setter
    def field_tile_threshold(self, value: Any) -> None: ...
    @property
    def field_tile_core(self) -> Any:
        ...
    @field_tile_core.setter
    def field_tile_core(self, value: Any) -> None: ...
    @property
    def refine_coarse_spacing(self) -> Any:
        ...
    @refine_coarse_spacing.setter
    def refine_coarse_spacing(self, value: Any) -> None: ...
    @property
    def refine_coarse_weight(self) -> Any:
        ...
    @refine_coarse_weight.setter
    def refine_coarse_weight(self, value: Any) -> None: ...
    @property
    def refine_coarse_iterations(self) -> Any:
        ...
    @refine_coarse_iterations.setter
    def refine_coarse_iterations(self, value: Any) -> None: ...
    @property
    def position_passes(self) -> Any:
        ...
    @position_passes.setter
    def position_passes(self, value: Any) -> None: ...
    @property
    def white_smoothness(self) -> Any:
        ...
    @white_smoothness.setter
    def white_smoothness(self, value: Any) -> None: ...
    @property
    def white_smoothness_iterations(self) -> Any:
        ...
    @white_smoothness_iterations.setter
    def white_smoothness_iterations(self, value: Any) -> None: ...
    @property
    def epochs(self) -> Any:
        ...
    @epochs.setter
    def epochs(self, value: Any) -> None: ...
    @property
    def overlap(self) -> Any:
        ...
    @overlap.setter
    def overlap(self, value: Any) -> None: ...
    @property
    def jitter(self) -> Any:
        ...
    @jitter.setter
    def jitter(self, value: Any) -> None: ...
    @property
    def oblique_lights(self) -> Any:
        ...
    @oblique_lights.setter
    def oblique_lights(self, value: Any) -> None: ...
    @property
    def plan_from_truth(self) -> Any:
        ...
    @plan_from_truth.setter
    def plan_from_truth(self, value: Any) -> None: ...
    @property
    def simulator(self) -> Any:
        ...
    @simulator.setter
    def simulator(self, value: Any) -> None: ...
    @property
    def simulate_position_error_texels(self) -> Any:
        ...
    @simulate_position_error_texels.setter
    def simulate_position_error_texels(self, value: Any) -> None: ...
    @property
    def simulate_exposure(self) -> Any:
        ...
    @simulate_exposure.setter
    def simulate_exposure(self, value: Any) -> None: ...
    @property
    def simulate_sigma_factor(self) -> Any:
        ...
    @simulate_sigma_factor.setter
    def simulate_sigma_factor(self, value: Any) -> None: ...
    @property
    def blur_widths(self) -> Any:
        ...
    @blur_widths.setter
    def blur_widths(self, value: Any) -> None: ...
    @property
    def blur_iterations(self) -> Any:
        ...
    @blur_iterations.setter
    def blur_iterations(self, value: Any) -> None: ...
    @property
    def blur_wavelengths(self) -> Any:
        ...
    @blur_wavelengths.setter
    def blur_wavelengths(self, value: Any) -> None: ...
    @property
    def band_limit(self) -> Any:
        ...
    @band_limit.setter
    def band_limit(self, value: Any) -> None: ...
    @property
    def refine(self) -> Any:
        ...
    @refine.setter
    def refine(self, value: Any) -> None: ...
    @property
    def max_range_um(self) -> Any:
        ...
    @max_range_um.setter
    def max_range_um(self, value: Any) -> None: ...
    @property
    def refine_history(self) -> Any:
        ...
    @refine_history.setter
    def refine_history(self, value: Any) -> None: ...
    @property
    def refine_loss(self) -> Any:
        ...
    @refine_loss.setter
    def refine_loss(self, value: Any) -> None: ...

class RecoveryResult:
    """What recover() returns."""
    @property
    def estimate(self) -> Any:
        """the recovered Heightfield (None with plan_only=True)"""
        ...
    @property
    def truth(self) -> Any:
        """the truth Heightfield (given or generated; None with observations)"""
        ...
    @property
    def observations(self) -> Any:
        """the Observations recovered from (simulated or given)"""
        ...
    @property
    def notes(self) -> List[str]:
        """the plan's choices, one line each (empty with observations)"""
        ...
    @property
    def warnings(self) -> List[str]:
        """check_acquisition's warnings"""
        ...
    @property
    def metrics(self) -> Any:
        """dict of arrays, one entry per reported step (the CLI's metrics.csv columns): stage (str),
        iteration (int64), loss, seconds (since the recovery started), height_rel_rmse and
        height_rel_rmse_plane_removed (float64; NaN without a truth or before heights exist).
        """
        ...
    @property
    def method(self) -> str:
        """'pipeline' or 'thesis'"""
        ...
    @property
    def loss(self) -> str:
        """the loss fitted, as a spec"""
        ...
    @property
    def noise(self) -> str:
        """the simulated noise, as a spec"""
        ...
    @property
    def height_range_um(self) -> float:
        """the truth's peak-to-valley (um), or the bound given with observations"""
        ...
    @property
    def plan(self) -> Any:
        """dict: the plan as the CLI's run.json states it before the run (its notes as "plan", the
        wavelengths, resolution, noise and loss, with photon noise "photon_plan" with its pilot); with
        plan_only=True also plan_only (True) and positions_um, the footprint centres in order.
        """
        ...
    @property
    def stopped(self) -> bool:
        """True when the callback stopped the run early"""
        ...
    @property
    def calibration(self) -> Any:
        """dict of the self-calibration (calibration.h): refined (str, e.g. 'exposure,sigma' or 'none'),
        sigma_p_scale (true sigma_p / stated), exposures (float64 (N,), reference ~ exposure * model,
        per observation of result.observations; None when not refined), position_offsets_um (float64
        (N, 2), true - stated centre; None when not refined), truth: with simulated acquisition errors
        the same keys with the true values (else None).
        """
        ...
    @property
    def uncertainty(self) -> Any:
        """with uncertainty=True: sigma of every height (mean removed), um, a float64 array (rows, cols); else None"""
        ...
    @property
    def median_sigma_um(self) -> float:
        """median of uncertainty (um; NaN without)"""
        ...
    @property
    def coverage_1sigma(self) -> float:
        """fraction of texels whose error lies within +-1 sigma (NaN without a truth or uncertainty)"""
        ...
    @property
    def coverage_2sigma(self) -> float:
        """fraction of texels whose error lies within +-2 sigma (NaN without a truth or uncertainty)"""
        ...
    @property
    def uncertainty_seconds(self) -> float:
        """wall time of the error bars, s (NaN without)"""
        ...
    @property
    def convergence(self) -> dict:
        """dict: whether the recovery converged, judged without the truth (convergence.h; the CLI's
        run.json "convergence"): converged (bool), floor ('poisson': the slices' photon-noise deviance,
        'noiseless': a study's exact slices, 'none': the misfit not judged), relative_misfit, reasons
        (list of str), warning (str, '' when converged), judged (bool: a floor or error bars judged the
        run; False: reported only); with 'poisson' also deviance, expected_deviance, deviance_sd,
        misfit_ratio (deviance / its noise floor), slices_off_floor (slices above their own floor) and
        worst_slice_excess, worst_slice_x_um, worst_slice_y_um (the worst one's deviance over its limit, its centre); after the model check model_misfit_gabor,
        model_misfit_field, model_selected; with error bars median_sigma_relative,
        predicted_error_relative; texture (where the run predicts a per-texel error: sigma_relative,
        sigma_source, texels, fraction, power_share, warned; texel_texture.h); where the check needed error bars, error_bars ('given', 'computed',
        'skipped', 'off', 'unavailable'), error_bars_note, and the cost rule's error_bars_predicted_seconds,
        run_seconds (CPU), error_bars_seconds, error_bars_predicted_bytes (the bars' predicted peak with what
        the run holds) and memory_limit_bytes (max_memory_gb, else the physical memory); where the bars were
        left out for their cost or memory, error_lower_bound_relative (the rms error they would predict,
        bounded from below by the slices' Fisher information alone) and error_lower_bound_seconds (CPU).
        """
        ...

def add_noise(values: Any, noise: Any, seed: int = ...) -> Any:
    """Simulated measurement noise (noise.h), deterministic in `seed`.

    values  a slice (float array of non-negative values, any shape: one slice) -> a new float64
            array of that shape; or Observation(s) -> a new list with noisy references, observation
            i seeded from (seed, i)
    noise   'none', 'poisson:N' (photon noise, N photons expected per slice, > 0; a slice summing to
            0 is unchanged) or 'gaussian:REL' (additive, sigma = REL x max, REL >= 0, clamped at 0)
    """
    ...

def amplitude(estimate: Any, reference: Any) -> float:
    """Squared error of amplitudes sqrt(I) (see Loss).
    estimate, reference: float arrays of the same shape, finite; an (n, n, c) array has c
    channels per pixel, any other shape one. The loss is a mean over pixels of a sum over channels.
    """
    ...

def built_with_hdf5() -> bool:
    """Whether this build reads and writes HDF5 observation files (CMake option WAVEBRDF_HDF5)."""
    ...

def check_acquisition(observations: Any, size: Any, texel_um: float, truth: Any = ...) -> List[str]:
    """Warnings (a list of str, empty when all is well) for observations too coarse or too sparse to
    determine the heights of a tile of `size` = N or (rows, cols) texels of texel_um (um):
    neighbouring windows overlapping < 60 %, texels farther than 2 sigma_p from every footprint,
    slices sampling u more than 4x as coarsely as Nyquist, fewer values than heights, and (with a
    truth Heightfield) slopes that reflect light off the slice.
    """
    ...

def cie1931_xyz(lambda_um: float) -> tuple:
    """CIE 1931 2-degree colour-matching functions (x, y, z) at a wavelength in um."""
    ...

def cmsle(estimate: Any, reference: Any, epsilon: float = ...) -> float:
    """Corrected mean squared log error with epsilon > 0 (see Loss).
    estimate, reference: float arrays of the same shape, finite; an (n, n, c) array has c
    channels per pixel, any other shape one. The loss is a mean over pixels of a sum over channels.
    """
    ...

def condition_surface(heights_um: Any, dx_um: float, dy_um: Any = ..., fill: str = ..., detrend: str = ..., crop: Any = ..., resample_um: Any = ..., periodic: str = ...) -> dict:
    """Conditions measured heights (as `wavebrdf convert`): a 2-D array in um, NaN where unmeasured,
    axis 0 along y with spacing dy_um (default dx_um), axis 1 along x with spacing dx_um. In order:
    crop (r0, c0, rows, cols), detrend ('none', 'mean', 'plane', 'poly:N'), fill ('none' refuses
    NaN where a later step needs every point; 'nearest', 'harmonic', 'mean'), resample_um (square
    texels, bilinear), periodic ('none', 'smooth' periodic-plus-smooth, 'mirror'). Returns a dict:
    heights_um, dx_um, dy_um, steps (one line each) and the seam's slope ratio before and after the
    periodic step (None without one). ValueError naming the argument on bad input.
    """
    ...

def design(target: str = ..., image: Any = ..., out: Any = ..., force: bool = ..., light: List[float[2]] = ..., lambda_um: Any = ..., spectral: Any = ..., band_um: List[float[2]] = ..., specular_cone: float = ..., cone_limit: float = ..., uniformity_limit: float = ..., region: str = ..., window: float = ..., view: Any = ..., view_cone: float = ..., size: int = ..., texel_um: float = ..., height_range_um: float = ..., levels: int = ..., level_step_um: float = ..., min_feature_um: float = ..., fabrication_error: str = ..., seed: int = ..., iterations: int = ..., refine_passes: int = ..., max_memory_gb: float = ..., delta_uv_tolerance: float = ..., delta_uv_ceiling: float = ..., start: Any = ..., continuation: str = ..., anneal_sweeps: Any = ...) -> dict:
    """A texel relief for a target appearance: `wavebrdf design` (docs/design.md), the same library run.

    target: 'anti-mirror', 'pattern:IMAGE.png', 'colour:#RRGGBB', 'iridescent:SPEC.json' (view and colour
    pairs), 'brdf:TABLE.exr' (a wavebrdf table or lobe file; its lights and wavelengths), or 'pattern' with
    image= (a 2-D grey array, rows along omega_x). light: the projected light direction. lambda_um (a laser, default 0.5)
    or spectral=N (white light, N equal-energy wavelengths over band_um). specular_cone, cone_limit,
    uniformity_limit, region (anti-mirror; a limit the relief breaks is also a UserWarning), window (pattern), view (default the mirror direction), view_cone,
    delta_uv_tolerance and delta_uv_ceiling (colour, iridescent; a colour the brightness trade leaves below Y 5 % is also a UserWarning) as the CLI's options; size, texel_um, height_range_um, levels, level_step_um (0: the default rule; the anti-mirror designs its own),
    min_feature_um with levels=0 (a grayscale relief: no lateral detail finer than it),
    fabrication_error ('scale:5%,blur:0.3um'), seed, iterations, refine_passes, max_memory_gb likewise.
    start: a size x size array of heights (um) on the run's levels to start from instead of a random
    relief (the CLI's --start HEIGHTS.exr; e.g. an earlier design's heights_um).
    continuation: 'auto' (the anti-mirror from a random start on an even size: designed on size/2 first,
    and on its halves while one holds an order besides the mirror one inside the specular cone at every
    wavelength, each tiled and continued; so is a colour, or an iridescent target with a pair, half of
    whose optimal-colour limit is below Y 10 %, with the view cone), 'off', or tile sizes such as
    '64,128' (the CLI's --continuation; anti-mirror, colour and iridescent).
    anneal_sweeps: the anti-mirror's annealed last stage (the CLI's --anneal-sweeps): heat-bath sweeps over
    the continuation's smallest tile after the loop designed it, then that tile repeated and scored;
    None: 400 where it applies (levels, a random start, no fabrication errors), 0: none.
    out: also write the run directory there (force: reuse one holding only a design's outputs).

    Returns a dict: heights_um (size x size float64, um), level (each texel's level index), levels_um,
    lambdas_um, texel_um, target and far_field (256 x 256 x 3 float32 pictures over +-picture_extent
    about the mirror direction), curve [(iteration, loss, phase, temperature)], metrics (design.json's
    metrics: model, exact, relaxed, ...) and design (all of design.json). The same options and seed give
    the same design as the CLI.
    """
    ...

def design_plate(picture: Any, palette: str, out: Any = ..., force: bool = ..., plate_pixel_um: float = ..., light: List[float[2]] = ..., spectral: int = ..., band_um: List[float[2]] = ..., view: Any = ..., view_cone: float = ..., size: int = ..., texel_um: float = ..., height_range_um: float = ..., levels: int = ..., level_step_um: float = ..., fabrication_error: str = ..., seed: int = ..., iterations: int = ..., refine_passes: int = ..., max_memory_gb: float = ...) -> dict:
    """A plate that shows a picture, one palette design per region: `wavebrdf design --target
    image:PICTURE.png --palette ...` (docs/design.md, "Plate"), the same library run.

    picture: a PNG path or a (rows, cols, 3) uint8 array of sRGB values. palette: '#RRGGBB;#RRGGBB;...'
    or 'dir:X,Y;dir:X,Y;...'. plate_pixel_um: a picture pixel's side on the plate, a whole number of
    tile periods (0: one period). The other options are the CLI's (white light: spectral >= 3; note
    the defaults here: size 128, levels 16). out: also write the run directory there.

    Returns a dict: heights_um (the plate, float64, um), levels_um, texel_um, assignment (each picture
    pixel's palette entry), appearance (views x rows x cols x 3 float32: each region's linear sRGB into
    the view cone under exact scalar diffraction of its tile), views (their names) and design (all of
    design.json). The same options and seed give the same plate as the CLI.
    """
    ...

def gauss_newton_matrix(observations: Any, estimate: Heightfield, loss: Any, *, step_um: float = ..., comm: Any = ...) -> numpy.ndarray:
    """The Gauss-Newton matrix G of `loss` at `estimate` (a Heightfield fitted to `observations`),
    dense, 1/um^2, a float64 array (n, n) over the texels in row-major order (n = rows x cols, at
    most 16384): the matrix height_uncertainty inverts ('poisson:N': the Fisher information of the
    photon counts; G times a constant vector is 0: the mean height is not observed). Its
    pseudo-inverse is the heights' covariance, so f^H G^+ f / n is the variance of a Fourier mode f
    (experiments/2026-11-30-photon-plan-variance.md). step_um: the forward differences' step (> 0);
    comm as height_uncertainty's. uncertainty.h.
    """
    ...

def gradient(heightfield: Heightfield, query: Query, weights: Any, precision: str = ..., *, path: str = ..., tolerance: float = ...) -> numpy.ndarray:
    """The gradient of sum(weights * render(heightfield, query, n)) with respect to the heightfield's
    values (texel units): float64 (rows, cols). weights: (n, n, 3), e.g. dL/dslice of a loss
    (Loss.value_and_gradient); see slice_gradient for how channels map to wavelengths. path and
    tolerance as render's.
    """
    ...

def height_mse(estimate: Any, truth: Any) -> float:
    """Mean squared difference of two heightfields (same shape) after removing each one's mean,
    which no slice can see; in the squared units of the inputs.
    """
    ...

def height_rel_rmse(estimate: Any, truth: Any) -> float:
    """RMS of (estimate - truth) in um after removing each one's mean, divided by the truth's
    peak-to-valley height (um): 0.01 is 1 %. Same sizes; the truth must not be flat. Each a
    Heightfield or a 2-D array (in the other's units: the ratio needs no unit when both are arrays).
    """
    ...

def height_rel_rmse_plane_removed(estimate: Any, truth: Any) -> float:
    """height_rel_rmse with the best-fit plane a + b x + c y (least squares over the texel centres)
    removed from estimate - truth: the error that is not a tilt (a tilt is not observable).
    Heightfields or 2-D arrays, as height_rel_rmse.
    """
    ...

def height_uncertainty(observations: Any, estimate: Heightfield, loss: Any, *, probe_spacing: int = ..., rounds: int = ..., cg_tolerance: float = ..., cg_iterations: int = ..., seed: int = ..., dense_max_texels: int = ..., comm: Any = ...) -> numpy.ndarray:
    """Error bars of `estimate` (a Heightfield recovered from `observations`): the standard deviation
    of every height (mean removed), um, a float64 array (rows, cols), from the curvature of `loss`
    (the loss it was fitted with: 'poisson:N' uses the Fisher information of N photons per slice;
    'amplitude', 'mse', 'cmsle:EPS' a noise variance estimated from the residuals) at the estimate:
    the diagonal of the inverse Gauss-Newton matrix G, formed sparse (one forward difference per
    texel of each observation's footprint): exact (dense Cholesky) up to dense_max_texels texels
    (0...16384), above by coloured probes (texels probe_spacing apart share one, 1...16; rounds
    sign draws, 1...64) and conjugate gradients on the formed G (cg_tolerance in (0, 1),
    cg_iterations 1...10000). comm: None or an mpi4py communicator (observations: this rank's
    share; every rank gets the same map). uncertainty.h, docs/recovery.md "Error bars".
    """
    ...

def image_gradient(heightfield: Any, dL_dimage: Any, *, plane_size_um: Any = ..., camera: Any, look_at: Any = ..., fov_deg: float = ..., resolution: Any = ..., point_light: Any = ..., directional_light: Any = ..., lambda_um: Any = ..., spectral: Any = ..., up: Any = ..., orthographic: bool = ..., view_width_um: float = ..., rotation_deg: float = ..., model: str = ..., sigma_p_um: float = ..., prune_tolerance: float = ..., power_w: float = ..., irradiance: float = ..., blackbody_k: Any = ..., texel_um: Any = ..., vscale: Any = ..., max_memory_gb: float = ..., sphere_radius_um: Any = ..., cylinder_radius_um: Any = ..., cylinder_length_um: Any = ..., precision: str = ..., disc_light: Any = ..., disc_order: int = ...) -> numpy.ndarray:
    """The gradient of a loss of render_image's picture with respect to the heights: given dL/dimage (rows, cols,
    3), returns dL/dh (the heightfield's rows, cols; per height value in texel widths, as the array or file
    holds it), through the point evaluator's adjoint (about twice the forward pass). The scene's keywords are
    render_image's; the gradient is of the double-precision picture (render_image(..., dtype='float64')).
    """
    ...

def invert(truth: Any = ..., observations: Any = ..., *, size: Any = ..., texel_um: Any = ..., vscale: Any = ..., x_um: Any = ..., y_um: Any = ..., sigma_p_um: float = ..., model: str = ..., lambda_um: Any = ..., spectral: Any = ..., light: Any = ..., resolution: int = ..., init: Any = ..., epochs: int = ..., optimizer: str = ..., lr: float = ..., beta1: float = ..., beta2: float = ..., decay: float = ..., loss: Any = ..., positions: Any = ..., seed: int = ..., callback: Any = ..., max_memory_gb: float = ..., quiet: Any = ..., path: str = ..., tolerance: float = ..., comm: Any = ...) -> InversionResult:
    """The inverse renderer (``wavebrdf invert`` without its output directory): recovers heights
    whose slices match references. Defaults are the thesis's first experiment (a generated 16x16
    truth, normal incidence, 32x32 spectral slice, flat start, Adam 0.01/0.9/0.99 with decay
    0.005, 300 epochs, CMSLE epsilon 1). Returns an InversionResult.

    truth         Heightfield, 2-D array (texel units) or EXR path; references are rendered from
                  it. Default: generated isotropic surface of `size` (rms 0.35 texel, correlation
                  2 texels, `seed`). Excludes `observations`.
    observations  Observation, list of them, or a JSON path (the CLI's --observations)
    size          N or (rows, cols), 1...16384: the generated truth, or the estimate with observations
    texel_um      texel width in um (> 0), vscale: vertical scale; default the truth
                  Heightfield's, else 1. Given, they apply to the truth and the estimate.
    x_um, y_um    footprint centre in um, any finite value, periodic (default: tile centre);
                  sigma_p_um 1e-6 to 1e6 and <= 10 tile periods (default 4)
    model         'OHS', 'GHS', 'ROHS', 'RGHS' or 'Kirchhoff'
    lambda_um     one wavelength in um, or spectral: N (1...256) or a list in um; default spectral 8
    light         projected light direction (wx, wy), wx^2 + wy^2 < 1; resolution: slice size n
    init          'flat', 'noisy:FRAC' (truth + uniform noise of width FRAC x its height range),
                  a Heightfield, a 2-D array or an EXR path
    epochs        0 to 10^7 (Adam steps or L-BFGS iterations); optimizer 'adam' or 'lbfgs'
    lr, beta1, beta2, decay   Adam's options (lr > 0, betas in [0, 1), decay >= 0 per epoch)
    loss          'cmsle:EPS', 'mse', 'amplitude', 'poisson:N' or a Loss
    positions     'fixed', 'random' (a new footprint position per epoch, Adam only), a list of
                  (x_um, y_um), or a JSON path ([[x_um, y_um], ...])
    seed          generated truth, noise and random positions
    callback      callback(metrics: dict, estimate: (rows, cols) float64 heights in texel units)
                  after each evaluated epoch (epoch 0 included); return False to stop early.
    max_memory_gb refuse (MemoryError, before the references are rendered) a run whose
                  estimated peak memory exceeds this many GB; 0 (default): the physical memory.
    quiet         progress (a tqdm bar if tqdm is installed, else a line on stderr): None (default)
                  shows it when stderr is a terminal or in Jupyter, False always, True never
    path          'auto', 'separable', 'fft' or 'direct': the path of every render and gradient
    tolerance     separable (GHS-type models) and fft paths: error bound relative to the slice
                  peak, 1e-12 to 1e-2 (default 1e-6)
    comm          None, or an mpi4py communicator: the observations are split over its ranks (each
                  renders or keeps its share, by footprint position) and the losses and gradients
                  summed over them (the same run as one process's up to the order of the sums);
                  every rank calls invert() with the same arguments and gets the same estimate and
                  metrics, while `observations` and `final_slices` are its own share; a callback's
                  False on any rank stops every rank.
    The run releases the GIL; Ctrl-C stops it at the end of an epoch (KeyboardInterrupt).
    """
    ...

def lbfgs_minimize(objective: Callable[..., Any], x0: Any, *, history: int = ..., max_iterations: int = ..., gradient_tolerance: float = ..., max_line_search: int = ..., callback: Any = ...) -> tuple:
    """Minimises objective(x) -> (value, gradient) from x0 by L-BFGS with a backtracking (Armijo)
    line search (Nocedal and Wright, Algorithms 7.4, 7.5, 3.1). x is passed as a new float64 array
    shaped like x0; gradient: any float array with as many values. Options: history >= 1 pairs,
    max_iterations >= 0, gradient_tolerance >= 0 (stop when max |g| <= it), max_line_search >= 1
    trials. callback(iteration, value), after each accepted step, may return False to stop.
    Returns (x, LbfgsResult). ValueError when f or its gradient at x0 is not finite.
    """
    ...

def measure_roughness(heightfield: Heightfield) -> dict:
    """What the recovery's planner reads from a known surface (roughness_plan.h, measure_roughness):
    a dict with range_um (peak to valley, um), rms_slope (rms |grad H|, central differences across
    the periodic tile: the model's slopes), rim_fraction (fraction of texels with |grad H| > 0.5,
    whose light leaves a slice under normal light), correlation_um (Sal, um), aspect (Str) and
    lay_deg (Std, degrees from x towards y). plan_acquisition(roughness=...) and
    recover(truth=...) plan for these.
    """
    ...

def mse(estimate: Any, reference: Any) -> float:
    """Mean squared error (see Loss).
    estimate, reference: float arrays of the same shape, finite; an (n, n, c) array has c
    channels per pixel, any other shape one. The loss is a mean over pixels of a sum over channels.
    """
    ...

def observation_loss(heightfield: Heightfield, observations: Any, loss: Any = ..., *, path: str = ..., tolerance: float = ...) -> tuple:
    """The mean over observations of loss(render(heightfield), reference) and its gradient with
    respect to the heightfield's values (texel units, float64 (rows, cols)), in double precision:
    (value, gradient). loss: a Loss or its spec ('cmsle:EPS', 'mse', 'amplitude', 'poisson:N').
    path and tolerance as wavebrdf.render_slice's.
    """
    ...

def plan_acquisition(*, rows: int = ..., cols: Any = ..., texel_um: float = ..., height_range_um: float = ..., sigma_p_um: float = ..., position_uncertainty_um: float = ..., overlap: float = ..., jitter: float = ..., lambda_um: float = ..., lambda_min_um: float = ..., lambda_max_um: float = ..., max_step_ratio: float = ..., lambdas_um: Any = ..., resolution: int = ..., light: Any = ..., model: str = ..., seed: int = ..., roughness: Any = ..., oblique_lights: bool = ...) -> AcquisitionPlan:
    """An acquisition that determines the heights of a rows x cols tile (acquisition.h): returns an
    AcquisitionPlan. Keyword arguments (PlanRequest's fields):

    rows, cols       heightfield size in texels (>= 1; cols defaults to rows); texel_um > 0 (um)
    height_range_um  expected peak-to-valley of the heights, um (>= 0): sets the wavelength ladder
    sigma_p_um       footprint sigma_p, um (> 0; 0: 1.5 texels, or k x position_uncertainty_um if
                     larger, k = 1). Window support D = 6 sigma_p.
    position_uncertainty_um  how far the stage may put a footprint from where it says, um rms per
                     coordinate (>= 0): with sigma_p planned, the footprint is made at least
                     that wide (the position loop converges up to ~sigma_p, docs/recovery.md)
    overlap          worst-case linear overlap 1 - d/D of neighbouring windows, 0.6 ... 0.95
    jitter           position jitter, fraction of the raster step, 0 ... 0.3
    lambda_um        base wavelength lambda0 (um), within lambda_min_um ... lambda_max_um (the
                     wavelengths the ladder may use); max_step_ratio: ladder step, 1.5 ... 100
    lambdas_um       given wavelengths (um) instead of the ladder; None: planned
    resolution       given slice size n (1...8192); 0: planned, n >= D/lambda (within 4x of Nyquist's
                     4D/lambda) and at least 48
    light            projected light direction (wx, wy), wx^2 + wy^2 < 1; model: 'OHS', 'ROHS', ...
    seed             the jitter
    roughness        None, or a known surface's measured roughness: a Heightfield (measured here) or
                     the dict measure_roughness returns. A rough, steep or strongly striated surface
                     then gets the rough-surface plan's long wavelengths (not with lambdas_um) and,
                     with oblique_lights (default True), its oblique lights, with notes: the plan
                     recover(truth=...) makes, given the truth's rows, cols, texel_um and
                     peak-to-valley (docs/recovery.md, "Rough surfaces")
    A height range the wavelengths cannot unwrap is a ValueError naming the largest they can.
    """
    ...

def planned_observations(plan: AcquisitionPlan) -> List[Observation]:
    """One Observation per (position, wavelength) of `plan`, with zero references (fill them with
    measurements, or use simulate_observations).
    """
    ...

def read_observation_index(path: Union[str, os.PathLike], max_memory_gb: float = ...) -> dict:
    """What an observation file holds, without its slices: a dict with 'queries' (a Query per
    observation, with its wavelengths), 'positions_um' (float64 (N, 2): x_um, y_um), 'resolution'
    and 'channels' (1 or 3). An HDF5 file reads its metadata only; a JSON file is read whole.
    """
    ...

def read_observations(path: Union[str, os.PathLike], indices: Any = ..., *, rank: int = ..., size: int = ..., max_memory_gb: float = ...) -> List[Observation]:
    """Observations from a file (what `wavebrdf invert|recover --observations` read): HDF5 (.h5,
    .hdf5, .cxi, or any file with the HDF5 signature; docs/observations_hdf5.md) or JSON.
    indices        positions in an HDF5 file to read (only their slices are read), in the order
                   given; None: all
    rank, size     only the observations rank `rank` of `size` holds (split by footprint position,
                   as the MPI runs split them: wavebrdf.observation_share), in file order
    max_memory_gb  refuse (MemoryError) a read needing more than this many GB (0: physical memory)
    """
    ...

def read_slice(path: Union[str, os.PathLike]) -> tuple:
    """Reads a slice EXR written by wavebrdf (render --out, genbrdf -o, a run's reference_/final_
    slices, observation files) or any RGB EXR.

    Returns (image, info): image a float32 array (n, n, 3), linear, in the slice's unit; info a dict
    of what the file says about itself: x_um, y_um, sigma_p_um (um), light (omega_i x, y), model,
    lambdas_um (list, um), resolution, channels (1: one wavelength, stored R = G = B; 3: sRGB),
    the heightfield's texel_um, vscale, heightfield_size (rows, cols) and heightfield_file (when
    known), unit (f_r, the BRDF, in 1/sr), made_by and version. An empty dict for a file without
    wavebrdf's attributes. RuntimeError names the file when it is unreadable or an attribute is
    hostile.
    """
    ...

def recover(truth: Any = ..., observations: Any = ..., *, size: Any = ..., texel_um: Any = ..., vscale: Any = ..., height_range_um: float = ..., correlation_texels: Any = ..., model: str = ..., light: Any = ..., sigma_p_um: float = ..., position_uncertainty_um: Any = ..., resolution: int = ..., lambdas_um: Any = ..., spectral: int = ..., noise: Any = ..., loss: Any = ..., method: str = ..., calibrate: Any = ..., uncertainty: bool = ..., check_error_bars: str = ..., target_error: float = ..., max_exposures: int = ..., seed: int = ..., plan_only: bool = ..., callback: Any = ..., max_memory_gb: float = ..., quiet: Any = ..., comm: Any = ..., settings: Any = ..., **kwargs: Any) -> RecoveryResult:
    """Heightfield recovery as ``wavebrdf recover`` runs it, without its output directory: the same
    options and seed give the same estimate. Returns a RecoveryResult.

    truth         Heightfield, 2-D array (texel units) or EXR path: the acquisition is planned for
                  it and its observations simulated. Default: a generated isotropic surface of
                  `size` (correlation_texels, peak-to-valley height_range_um, `seed`). Excludes
                  `observations`.
    observations  Observation(s) or a JSON path (the CLI's --observations): recovered as given, on
                  a `size` grid, with height_range_um as the bound for unwrapping
    size          N or (rows, cols), 1...16384 (default 32)
    texel_um      texel width in um (> 0), vscale: vertical scale; default the truth Heightfield's,
                  else 2 um and 1. Given, they apply to the truth and the estimate.
    height_range_um  generated truth: peak-to-valley in um (> 0, default 2: +-1 um); with
                  observations: bound on the height range
    correlation_texels  generated truth: correlation length in texels (> 0; None: 4). With a given
                  truth: the stated correlation the acquisition is planned for (as a user without
                  the truth would plan it) instead of the truth's measured roughness
    model         'OHS', 'ROHS', 'GHS' or 'RGHS' (GHS-type through the separable proxy); light: (wx, wy), |w| < 1
    sigma_p_um    footprint sigma_p in um (0: the planner's, 1.5 texels or position_uncertainty_um
                  if larger)
    position_uncertainty_um  how far the stage may put a footprint from where it says, um rms per
                  coordinate (the CLI's --position-uncertainty-um): the planner makes sigma_p at
                  least this and the position loop searches lost positions 4x as far; None: the
                  simulated error's rms (settings.simulate_position_error_texels x texel_um), else 0
    resolution    slice size n, 1...8192 (0: the planner's: 48, or more where the window needs it)
    lambdas_um    wavelengths in um (None: the planner's ladder for the height range)
    spectral      white light (the CLI's --spectral): N >= 2 makes every planned observation one RGB
                  slice of a broadband source sampled at N wavelengths (no laser); 0: laser slices
    noise         simulated noise: 'none', 'poisson:N' (photons per slice) or 'gaussian:REL'
    loss          a spec or Loss; None: matched to the noise for the pipeline (amplitude without
                  noise, poisson:N, mse), cmsle:1 for the thesis's method
    method        'pipeline' (blurred fit, field retrieval, unwrapping, refinement) or 'thesis'
                  (Adam, one observation per epoch; settings.epochs)
    calibrate     self-calibration, the CLI's --calibrate: None or 'none' (default), 'positions',
                  'exposure', 'sigma' (comma-separated or a sequence), or 'all'; the refined values
                  are in result.calibration
    uncertainty   True: also the error bars (height_uncertainty with the run's loss): the result's
                  uncertainty (sigma per texel, um), median_sigma_um and, with a truth,
                  coverage_1sigma / coverage_2sigma (wavebrdf recover --uncertainty)
    check_error_bars  the convergence check's own error bars where it needs them (photon counts with
                  the misfit on the floor, or a loss without a noise level): 'auto' (computed when
                  predicted to take at most the recovery's own CPU time), 'always' or 'off' (the
                  CLI's --check-error-bars; result.convergence['error_bars'] says what was done)
    target_error  photon noise: the rms height error the planner aims at, a fraction of the truth's
                  peak to valley (default 0.01; 0: off): where the planned slices' predicted error
                  (their error bars and bias; within 1.5x of the target scaled by a pilot of the
                  recovery on 32x32 to 64x64 tiles, result.notes) is more, every slice is taken as several exposures of the noise's N photons, summed
                  (result.noise then says k*N; result.notes says why), at most max_exposures
                  (1 ... 10000, default 16); the CLI's --target-error, --max-exposures
    seed          generated truth, position jitter, noise, the thesis's draws
    plan_only     True: plan the acquisition (with photon noise the exposures and their pilot) as
                  the run would and stop there, nothing simulated or recovered (the CLI's
                  --plan-only): result.plan holds the plan with "positions_um", the footprint
                  centres; result.observations the planned slices (no references); estimate None
    callback      callback(metrics: dict with stage, kind, total (the stage's planned iterations, 0
                  for a result: what the progress bars show), iteration, loss, seconds,
                  height_rel_rmse) after every reported step; return False to stop early.
    max_memory_gb refuse (MemoryError, before any work) a run whose estimated peak memory exceeds
                  this many GB; 0 (default): the physical memory
    quiet         progress (a tqdm bar per stage if tqdm is installed, else a line on stderr): None
                  (default) shows it when stderr is a terminal or in Jupyter, False always, True never
    comm          None (default: one process) or an mpi4py communicator (e.g. MPI.COMM_WORLD, under
                  mpiexec): every rank passes the same arguments and keeps its share of the
                  observations (result.observations: this rank's); the sums are allreduced, every
                  rank gets the same estimate, only rank 0 shows progress (docs/scale.md). The
                  thesis's method runs on one process only.
    settings      a RecoverSettings: the rarely used settings (iterations, tiles, the position
                  loop's passes, white light's continuation, the planner's overlap and lights, a
                  study's simulated acquisition errors); None: the defaults. Their names as
                  keywords of recover() still work for now, with a FutureWarning.
    Whether the run converged is judged without the truth, as the CLI judges it (docs/recovery.md,
    "Did it converge?"): result.convergence; when it did not, its warning is also the last entry
    of result.warnings (as in the CLI's run.json).
    The run releases the GIL; Ctrl-C stops it within about a second (KeyboardInterrupt).
    """
    ...

def recover_heights(observations: Any, size: Any, texel_um: float, vscale: float = ..., *, truth: Any = ..., calibrate: Any = ..., callback: Any = ..., comm: Any = ..., settings: Any = ..., **kwargs: Any) -> Any:
    """The heightfield whose slices match `observations`, from a flat start (recover.h): a blurred fit,
    phase retrieval of the field per wavelength on a refined object grid, unwrapping, then L-BFGS
    on the heights in the full model. Returns a Heightfield (size, texel units with texel_um and
    vscale). With default settings it runs the schedule `wavebrdf recover` and recover() run for a
    smooth surface.

    settings            a RecoverSettings (None: the defaults): the schedule's settings it shares
                        with recover() (field_iterations, refine_iterations, field tiles, the coarse
                        space, position_passes, white light's continuation) and the stages' own
                        (blur_widths, blur_iterations, blur_wavelengths, band_limit, refine,
                        max_range_um, refine_history, refine_loss; help(RecoverSettings));
                        one of the acquisition's (overlap, simulate_*, ...) set is a ValueError. Their
                        names as keywords of recover_heights still work for now, with a FutureWarning.
    Metrics stages: 'blur:S', 'blur', 'field:LAMBDA', 'unwrap', 'refine'.
    comm                None (one process) or an mpi4py communicator: `observations` is then this
                        rank's share (every rank calls with its own; docs/scale.md), the sums are
                        allreduced and every rank returns the same heights.
    calibrate           self-calibration (calibration.h): None (default: the acquisition is exact;
                        returns a Heightfield), or 'positions', 'exposure', 'sigma' as a comma-
                        separated string or a sequence of them, 'all' or 'none': returns a tuple
                        (Heightfield, dict) with the refined values: refined (str), sigma_p_scale
                        (true sigma_p / stated), exposures (float64 (N,): reference ~ exposure *
                        model, per observation in the order given; None when not refined),
                        position_offsets_um (float64 (N, 2): true - stated centre; or None).

    observations  Observation(s) at several positions and wavelengths (OHS / ROHS single-wavelength
                  ones feed the blurred fit and the fields; all feed the refinement and Adam); their
                  weights count (a pixel of weight 0 is out of every misfit; docs/recovery.md)
    size          N or (rows, cols) of the estimate, 1...16384; texel_um > 0 (um), vscale finite
    truth         a Heightfield of that size, or None: only feeds height_rel_rmse in the metrics
    callback      callback(metrics: dict with stage, kind (the stage's kind: 'field:', 'refine', ...),
                  total (its planned iterations; 0 for a result), iteration, loss, seconds,
                  height_rel_rmse (NaN without a truth)) after every reported step; return False to stop early
                  (the estimate so far is returned). The run releases the GIL; Ctrl-C stops it
                  at the next step (KeyboardInterrupt).
    """
    ...

def recover_heights_thesis(observations: Any, size: Any, texel_um: float, vscale: float = ..., *, truth: Any = ..., epochs: int = ..., lr: float = ..., beta1: float = ..., beta2: float = ..., decay: float = ..., loss: Any = ..., seed: int = ..., report_every: int = ..., callback: Any = ...) -> Heightfield:
    """The thesis's method as a baseline (baseline.h): Adam on `loss` (default cmsle:1), one
    observation drawn at random (from `seed`) per epoch, from a flat start. Returns a Heightfield.
    epochs >= 0; lr > 0, beta1 and beta2 in [0, 1), decay >= 0 per epoch (the thesis's 0.01, 0.9,
    0.99, 0.005); the callback sees stage 'thesis' every report_every (>= 1) epochs and the last.

    observations  Observation(s) at several positions and wavelengths (OHS / ROHS single-wavelength
                  ones feed the blurred fit and the fields; all feed the refinement and Adam); their
                  weights count (a pixel of weight 0 is out of every misfit; docs/recovery.md)
    size          N or (rows, cols) of the estimate, 1...16384; texel_um > 0 (um), vscale finite
    truth         a Heightfield of that size, or None: only feeds height_rel_rmse in the metrics
    callback      callback(metrics: dict with stage, kind (the stage's kind: 'field:', 'refine', ...),
                  total (its planned iterations; 0 for a result), iteration, loss, seconds,
                  height_rel_rmse (NaN without a truth)) after every reported step; return False to stop early
                  (the estimate so far is returned). The run releases the GIL; Ctrl-C stops it
                  at the next step (KeyboardInterrupt).
    """
    ...

@overload
def render(heightfield: Heightfield, query: Query, resolution: int = ..., precision: str = ..., *, path: str = ..., tolerance: float = ...) -> numpy.ndarray:
    """The BRDF slice of a Heightfield for a Query: (resolution, resolution, 3) linear RGB, float64
    (precision='double') or float32 ('float'); resolution 1...8192.
    path        'auto' (chosen by cost), 'separable' (matrix products), 'fft' (the FFT engine) or
                'direct' (every pixel sums every kernel); a path the model has not is a ValueError
    tolerance   separable (GHS, RGHS, Kirchhoff) and fft paths: error bound relative to the slice
                peak, 1e-12 to 1e-2 (default 1e-6)
    """
    ...
@overload
def render(gabor: GaborRep, query: Query, resolution: int = ..., precision: str = ..., *, path: str = ..., tolerance: float = ...) -> numpy.ndarray:
    """The same from a GaborRep made for this query's footprint (the kernels are not gathered again); path and
    tolerance as above.
    """
    ...

def render_image(heightfield: Any, *, plane_size_um: Any = ..., camera: Any, look_at: Any = ..., fov_deg: float = ..., resolution: Any = ..., point_light: Any = ..., directional_light: Any = ..., lambda_um: Any = ..., spectral: Any = ..., up: Any = ..., orthographic: bool = ..., view_width_um: float = ..., rotation_deg: float = ..., model: str = ..., sigma_p_um: float = ..., prune_tolerance: float = ..., power_w: float = ..., irradiance: float = ..., blackbody_k: Any = ..., texel_um: Any = ..., vscale: Any = ..., max_memory_gb: float = ..., sphere_radius_um: Any = ..., cylinder_radius_um: Any = ..., cylinder_length_um: Any = ..., precision: str = ..., disc_light: Any = ..., disc_order: int = ..., dtype: str = ...) -> Any:
    """A camera picture of a sample carrying the heightfield (docs/image.md), as `wavebrdf image` renders it:
    an array (rows, cols, 3) of linear sRGB radiance in W/(m^2 sr): float32 as the EXR (the default), or
    dtype='float64' for the values before that rounding.

    heightfield: a Heightfield, an EXR path or a 2-D array of heights in texel widths.
    plane_size_um: W or (W, H), the plate (x by y) centred at the origin, the heightfield tiled on it; or
    sphere_radius_um=R (a sphere about the origin, poles on y), or cylinder_radius_um=R with
    cylinder_length_um=L (about the x axis, centred): exactly one of them (docs/image.md states the mappings).
    camera, look_at, up: (x, y, z) in um; z is the plate's normal, x/y the heightfield's rows/columns.
    fov_deg: pinhole field of view across the rows; orthographic=True with view_width_um instead.
    resolution: N or (rows, cols).
    point_light: (x, y, z) um or a list of them; directional_light: direction(s) towards the light;
    disc_light: (x, y, z, r) um, a Lambertian disc facing the origin, integrated by disc_order n
    (n Gauss-Legendre radii x 2n angles).
    lambda_um: one wavelength (a laser) or spectral=K wavelengths over 0.36-0.83 um.
    sigma_p_um: every pixel's footprint (0: from the pixel's projected size).
    prune_tolerance: kernel pruning bound relative to each pixel's largest possible value (0: full sum).
    precision: 'double' or 'float' (the sum in single precision, as the CLI's --precision float).
    power_w (point), irradiance (directional, W/m^2), blackbody_k (spectrum; None: white).
    """
    ...

def render_slice(heights: Any, *, resolution: int, texel_um: Any = ..., vscale: Any = ..., x_um: Any = ..., y_um: Any = ..., sigma_p_um: float = ..., lambda_um: Any = ..., spectral: Any = ..., light: Any = ..., model: str = ..., path: str = ..., tolerance: float = ..., comm: Any = ...) -> Any:
    """render_slice(heights, *, resolution, texel_um=None, vscale=None, x_um=0.0, y_um=0.0, sigma_p_um=10.0, lambda_um=None, spectral=None, light=(0, 0), model='OHS', path='auto', tolerance=1e-06, comm=None)

    One BRDF slice f_r (1/sr) of the heightfield `heights`, shape (resolution, resolution, 3),
    linear RGB. The same as `wavebrdf render` with the same options. With batch axes
    (below): (batch..., resolution, resolution, 3), one slice per item.
    With comm (an mpi4py communicator; every rank makes the same call): the items are split
    over its ranks, rank 0 gets the whole array (equal to one process's), the others None.

    heights     float32 or float64 array (rows, cols), or (..., rows, cols) for a batch (below),
                finite, in texel units. float64 renders
                in double precision, float32 in single (the CLI's --precision); the result has the
                same dtype.
    texel_um    texel width w in um, 1e-4 to 1e4 (default: a Heightfield's own, else 1; a value
                that differs from a Heightfield's is refused)
    vscale      vertical scale v, 0 or 1e-6 <= |v| <= 1e4 (default: a Heightfield's own, else 1):
                height in um = vscale * texel_um * heights
    x_um, y_um  footprint centre in um along x (rows) and y (columns), any finite value (periodic;
                default 0); arrays for a batch (below)
    sigma_p_um  footprint (coherence) standard deviation sigma_p in um, 1e-6 to 1e6 and at most
                10 times the longer tile period (default 10)
    lambda_um   one wavelength in um, 0.01 to 1000: R = G = B = its slice. Default 0.5 when spectral is None.
    spectral    N (1...256): the library's N wavelengths over 0.36-0.83 um (the CLI's --spectral N),
                or a list of wavelengths in um; mapped to linear sRGB through the CIE 1931 curves.
                Excludes lambda_um.
    light       projected direction towards the light (wx, wy), wx^2 + wy^2 < 1 (default (0, 0));
                an array (..., 2) for a batch (below)
    resolution  slice size n, 1...8192 (required); pixel (i, j) is omega_o =
                ((i + 1/2) / n * 2 - 1, (j + 1/2) / n * 2 - 1), zero outside the unit disk
    model       'OHS' (default), 'GHS', 'ROHS', 'RGHS' or 'Kirchhoff'
    path        'auto' (chosen by cost), 'separable' (matrix products), 'fft' (the FFT engine) or
                'direct' (every pixel sums every kernel); a path the model has not is a ValueError
    tolerance   separable (GHS, RGHS, Kirchhoff) and fft paths: error bound relative to the slice
                peak, 1e-12 to 1e-2 (default 1e-6)

    Batches: heights may have leading batch axes (..., rows, cols); light may be (2,) or (..., 2);
    x_um and y_um may be scalars or arrays. The batch shape is the NumPy broadcast of
    heights.shape[:-2], light.shape[:-1], numpy.shape(x_um) and numpy.shape(y_um) (right-aligned;
    each axis equal or 1), and item [i...] renders heights[i...], light[i...], x_um[i...], y_um[i...]
    with each argument indexed as broadcasting repeats it. render_slice returns (batch..., n, n, 3);
    slice_gradient takes weights of exactly that shape and returns an array shaped like heights
    whose entries sum the gradients of every item that read them (so heights broadcast over lights
    get the sum over the lights). sigma_p_um, the wavelengths and the model are shared. The items
    run in one library call spread over the threads (wavebrdf/batch.h); each equals the single call
    (to rounding of a parallel sum, ~1e-12 relative in float64). A single query (2-D heights, one
    light pair, scalar positions) keeps the shapes (n, n, 3) and (rows, cols).
    The last two axes of heights are always one surface. With batch axes, a surface that looks like
    an image's channels is refused (ValueError): 1 texel wide, or 2 to 4 texels wide and at least 4
    times longer, when that is narrower than the footprint (6 sigma_p) or is the last axis of an
    (H, W, C) array with H and W both at least 4 C. For an image-like export (rows, cols, 1 to 4)
    pass heights[..., 0]; narrow surfaces of a real batch render one 2-D array at a time.
    """
    ...

def rgb_gamma_mse(estimate: Any, reference: Any) -> float:
    """Reporting metric of the thesis (Fig. 5.3), mean over pixels and channels of
    (T(I) - T(R))^2 with T(x) = x / (1 + x) (rgb_mse) or (x / (1 + x))^(1/2.2)
    (rgb_gamma_mse). (n, n, 3) RGB or (n, n) / (n, n, 1) grey slices.
    """
    ...

def rgb_mse(estimate: Any, reference: Any) -> float:
    """Reporting metric of the thesis (Fig. 5.3), mean over pixels and channels of
    (T(I) - T(R))^2 with T(x) = x / (1 + x) (rgb_mse) or (x / (1 + x))^(1/2.2)
    (rgb_gamma_mse). (n, n, 3) RGB or (n, n) / (n, n, 1) grey slices.
    """
    ...

def simulate_observations(truth: Heightfield, plan: AcquisitionPlan, noise: Any = ..., seed: int = ...) -> List[Observation]:
    """The planned observations of `truth` (a Heightfield), rendered in double precision, with
    `noise` added: 'none', 'poisson:N' (N photons expected per slice, > 0) or 'gaussian:REL'
    (sigma REL x the slice's peak, >= 0, clamped at 0). Observation i's noise is drawn from
    (seed, i). Returns a list of Observations.
    """
    ...

def slice_gradient(heights: Any, weights: Any, *, resolution: int, texel_um: Any = ..., vscale: Any = ..., x_um: Any = ..., y_um: Any = ..., sigma_p_um: float = ..., lambda_um: Any = ..., spectral: Any = ..., light: Any = ..., model: str = ..., path: str = ..., tolerance: float = ...) -> numpy.ndarray:
    """slice_gradient(heights, weights, *, resolution, **the options of render_slice)

    The gradient of sum(weights * render_slice(heights, ...)) with respect to `heights`
    (texel units), a vector-Jacobian product by the library's adjoint: an array shaped
    and typed like `heights`. For a loss L of the slice, weights = dL/dslice gives
    dL/dheights.

    weights     float32/float64 array (resolution, resolution, 3), or (batch..., resolution,
                resolution, 3) for a batch (below); one weight per pixel and channel.
                One wavelength: R = G = B, so the three channels' weights add.
                Spectral: each wavelength gets sum_c M[c, l] * weights[..., c]
                with M = spectral_to_srgb_weights(wavelengths). Finite inside the unit
                disk; pixels outside it are not rendered and their weights are ignored,
                whatever they hold (the inf or NaN of d/dI sqrt(I) where I = 0 included).

    heights     float32 or float64 array (rows, cols), or (..., rows, cols) for a batch (below),
                finite, in texel units. float64 renders
                in double precision, float32 in single (the CLI's --precision); the result has the
                same dtype.
    texel_um    texel width w in um, 1e-4 to 1e4 (default: a Heightfield's own, else 1; a value
                that differs from a Heightfield's is refused)
    vscale      vertical scale v, 0 or 1e-6 <= |v| <= 1e4 (default: a Heightfield's own, else 1):
                height in um = vscale * texel_um * heights
    x_um, y_um  footprint centre in um along x (rows) and y (columns), any finite value (periodic;
                default 0); arrays for a batch (below)
    sigma_p_um  footprint (coherence) standard deviation sigma_p in um, 1e-6 to 1e6 and at most
                10 times the longer tile period (default 10)
    lambda_um   one wavelength in um, 0.01 to 1000: R = G = B = its slice. Default 0.5 when spectral is None.
    spectral    N (1...256): the library's N wavelengths over 0.36-0.83 um (the CLI's --spectral N),
                or a list of wavelengths in um; mapped to linear sRGB through the CIE 1931 curves.
                Excludes lambda_um.
    light       projected direction towards the light (wx, wy), wx^2 + wy^2 < 1 (default (0, 0));
                an array (..., 2) for a batch (below)
    resolution  slice size n, 1...8192 (required); pixel (i, j) is omega_o =
                ((i + 1/2) / n * 2 - 1, (j + 1/2) / n * 2 - 1), zero outside the unit disk
    model       'OHS' (default), 'GHS', 'ROHS', 'RGHS' or 'Kirchhoff'
    path        'auto' (chosen by cost), 'separable' (matrix products), 'fft' (the FFT engine) or
                'direct' (every pixel sums every kernel); a path the model has not is a ValueError
    tolerance   separable (GHS, RGHS, Kirchhoff) and fft paths: error bound relative to the slice
                peak, 1e-12 to 1e-2 (default 1e-6)

    Batches: heights may have leading batch axes (..., rows, cols); light may be (2,) or (..., 2);
    x_um and y_um may be scalars or arrays. The batch shape is the NumPy broadcast of
    heights.shape[:-2], light.shape[:-1], numpy.shape(x_um) and numpy.shape(y_um) (right-aligned;
    each axis equal or 1), and item [i...] renders heights[i...], light[i...], x_um[i...], y_um[i...]
    with each argument indexed as broadcasting repeats it. render_slice returns (batch..., n, n, 3);
    slice_gradient takes weights of exactly that shape and returns an array shaped like heights
    whose entries sum the gradients of every item that read them (so heights broadcast over lights
    get the sum over the lights). sigma_p_um, the wavelengths and the model are shared. The items
    run in one library call spread over the threads (wavebrdf/batch.h); each equals the single call
    (to rounding of a parallel sum, ~1e-12 relative in float64). A single query (2-D heights, one
    light pair, scalar positions) keeps the shapes (n, n, 3) and (rows, cols).
    The last two axes of heights are always one surface. With batch axes, a surface that looks like
    an image's channels is refused (ValueError): 1 texel wide, or 2 to 4 texels wide and at least 4
    times longer, when that is narrower than the footprint (6 sigma_p) or is the last axis of an
    (H, W, C) array with H and W both at least 4 C. For an image-like export (rows, cols, 1 to 4)
    pass heights[..., 0]; narrow surfaces of a real batch render one 2-D array at a time.
    """
    ...

def spectral_to_srgb_weights(lambdas_um: List[float]) -> numpy.ndarray:
    """The (3, N) matrix M mapping values at the N wavelengths (um) to linear sRGB (CIE 1931,
    Bradford to D65): rgb[c] = sum_l M[c, l] f(lambda_l). A constant spectrum maps to grey.
    """
    ...

def spectral_wavelengths_um(count: int) -> List[float]:
    """The library's N wavelengths in um: 0.36 + (k + 1/2) * 0.47 / N (N = 8: genBrdf's samples)."""
    ...

def surface_acf(heightfield: Any) -> dict:
    """The areal autocorrelation function (ISO 25178-2; not wrapped, normalised by the overlapping
    points and to 1 at zero lag): a dict with the radial average lag_um, acf, count, and the 2-D
    ACF acf_2d ((2 rows - 1) x (2 cols - 1) in the image frame, zero lag at the centre) with its
    lag steps step_x_um, step_y_um.
    """
    ...

def surface_psd(heightfield: Any) -> dict:
    """The power spectral density of a heightfield (periodic, no window): a dict with the radial
    average q_per_um (rad/um), psd_um4 (um^4) and count (FFT bins per ring), and the 2-D PSD
    psd_2d_um4 (image frame: axis 0 along y, axis 1 along x, zero frequency at the centre) with its
    steps dq_x_per_um, dq_y_per_um. sum(psd_2d_um4) * dq_x * dq_y / (2 pi)^2 = Sq^2.
    """
    ...

def surface_stats(heightfield: Any) -> dict:
    """The ISO 25178-2 areal parameters of a heightfield (a Heightfield, an EXR path or a 2-D array of
    heights in texel units with texel 1 um), over the whole tile, the mean removed: a dict with
    Sa, Sq, Sp, Sv, Sz (um), Ssk, Sku, Sdq, Sdr (%), Sal (um), Str, Std (degrees, the lay's
    direction from x towards y, x along the heightfield's rows) and acf_decayed_everywhere (False:
    Str is an upper bound). Definitions: docs/surfaces.md, "Parameters". ValueError for a tile
    smaller than 2 x 2.
    """
    ...

def with_height_range(heightfield: Heightfield, range_um: float) -> Heightfield:
    """`heightfield` scaled about its mean to the peak-to-valley height range_um (um, > 0); texel
    width and vscale unchanged. A flat heightfield is a ValueError.
    """
    ...

def write_fabrication_exports(out_dir: str, heights_um: Any, texel_um: float, height_range_um: float, levels: int = ..., max_stl_gb: float = ...) -> dict:
    """Writes the fabrication files of a relief of square texels (docs/fabrication.md) into the
    existing directory out_dir: heights.png (16-bit grey, 0...height_range_um, the scale in text
    chunks), heights.stl (a closed binary STL solid in um; skipped beyond max_stl_gb, with a note),
    heights.x3p (ISO 25178-72, float64 um; skipped with x3p_note when the x3p plugin does not load or
    its copies, 24 bytes a texel, exceed max_stl_gb) and, when levels > 0, masks_01.png ... and masks.json (the masks of multi-step lithography:
    log2 K binary-weighted masks when K is a power of two, else K - 1 cumulative ones; each height
    must then be a level k * height_range_um / (levels - 1)).

    heights_um: 2-D array (rows, cols) of heights in um, within 0...height_range_um; texel_um:
    texel width in um. Returns a dict: heights_png, heights_stl ('' when skipped), masks_json,
    masks (list of {path, depth_um, weight}), stl_triangles, note, heights_x3p ('' when skipped),
    x3p_note. ValueError for a bad value
    (naming the texel), RuntimeError when a file cannot be written.
    """
    ...

def write_observations(path: Union[str, os.PathLike], observations: Any, references: str = ...) -> None:
    """Writes observations (the formats read_observations and `wavebrdf invert|recover
    --observations` read), atomically: one HDF5 file for a path ending in .h5, .hdf5 or .cxi
    (slices as float32, one resolution and channel count for all; docs/observations_hdf5.md),
    else JSON. references (JSON only): 'inline' (values in the JSON, exact) or 'exr' (float EXR
    files NAME/slice_0000.exr ... beside the JSON, NAME its file name without the extension: what
    `wavebrdf recover --save-observations` writes).
    """
    ...
