"""BRDF tables: the slices of one footprint over a regular grid of light directions
(``wavebrdf table``, docs/table.md).

The light grid is the slice convention applied to the light, scaled by ``max_light_sin``
(sin theta_i at the grid's edge): light (a, b) of a rows x cols grid is

    omega_i = (max_light_sin * ((a + 1/2) / rows * 2 - 1), max_light_sin * ((b + 1/2) / cols * 2 - 1)),

a along x (``light_x``), b along y (``light_y``); only lights with |omega_i| <= max_light_sin are
rendered (``rendered``), the others are all zero. Each entry is an n x n RGB slice over the
projected outgoing direction, pixel (p, q) at omega_o = ((p + 1/2) / n * 2 - 1, (q + 1/2) / n * 2 - 1),
zero outside the unit disk: f_r in 1/sr (one wavelength: R = G = B; several: CIE 1931 to linear
sRGB), exactly what ``wavebrdf.render`` returns for that light (in float32).
"""
import os

from . import _core

__all__ = ["BrdfTable", "lobe_brdf", "lobe_table", "read_table", "render_table"]


class BrdfTable:
    """A BRDF table and its axes.

    values          float32 array (rows, cols, n, n, 3): values[a, b, p, q, c] is f_r in 1/sr for
                    light (light_x[a], light_y[b]) at omega_o = (omega_o[p], omega_o[q]), channel c
    light_x         float64 (rows,): omega_i,x of each light row (projected, dimensionless)
    light_y         float64 (cols,): omega_i,y of each light column
    rendered        bool (rows, cols): True where |omega_i| <= max_light_sin (the others are 0)
    omega_o         float64 (n,): the projected outgoing direction of slice row / column p
    max_light_sin   sin theta_i at the light grid's edge, 0 < s < 1
    resolution      n
    query           wavebrdf.Query: footprint (x_um, y_um, sigma_p_um in um), model and
                    wavelengths; its light is (0, 0) (each entry has its own)
    lambdas_um      the wavelengths in um; spectral: True when mixed to linear sRGB (CIE 1931)
    precision       'float' or 'double': the precision each slice was rendered in
    heightfield_size, texel_um, vscale   the surface: (rows, cols) texels, texel width in um,
                    vertical scale
    version         the wavebrdf version that rendered it
    source          '' for a table rendered from a surface; an analytic lobe's description
                    (lobe_table) otherwise
    """

    def __init__(self, fields):
        import numpy as np

        for name, value in fields.items():
            setattr(self, name, value)
        n = self.resolution
        self.omega_o = (np.arange(n) + 0.5) / n * 2.0 - 1.0

    def light(self, a, b):
        """The projected light direction (wx, wy) of entry (a, b)."""
        return (float(self.light_x[a]), float(self.light_y[b]))

    def __repr__(self):
        rows, cols = self.values.shape[:2]
        return (f"BrdfTable({rows}x{cols} lights within sin {self.max_light_sin:g}, "
                f"{self.resolution}x{self.resolution} slices, {self.query!r})")


def read_table(path):
    """Reads a table file written by ``wavebrdf table`` (or render_table(out=...)) into a
    BrdfTable. RuntimeError naming the file when it is not such a table (missing or
    inconsistent attributes, a mosaic whose size disagrees with them, non-finite values)."""
    return BrdfTable(_core._read_table(str(path)))


def render_table(heightfield, query, *, lights=(32, 32), max_light_sin=0.9, resolution=64, precision="float",
                 max_memory_gb=0.0, out=None, path="auto", tolerance=1e-6, comm=None):
    """Renders the BRDF table of one footprint over a grid of lights (``wavebrdf table``).

    heightfield     a wavebrdf.Heightfield, an EXR path (its own texel_um and vscale, else 1),
                    or a 2-D array of heights in texel
                    units (texel_um 1, vscale 1; build a Heightfield for other scales)
    query           wavebrdf.Query: footprint, model and wavelengths (its light is ignored)
    lights          N or (rows, cols): lights along omega_i,x and omega_i,y, 1...16384, with
                    rows * resolution and cols * resolution at most 16384
    max_light_sin   sin theta_i at the grid's edge, 0 < s < 1 (default 0.9)
    resolution      n of each n x n slice, 1...8192 (default 64)
    precision       'float' or 'double': each slice rendered in that precision (values float32)
    max_memory_gb   refuse (MemoryError) a table whose estimate exceeds this many GB; 0: the
                    physical memory
    out             optional path: also write the table file there (atomically)
    path            'auto', 'separable', 'fft' or 'direct' (as wavebrdf.render_slice's)
    tolerance       separable (GHS-type models) and fft paths: error bound relative to each
                    slice's peak, 1e-12 to 1e-2 (default 1e-6)
    comm            None, or an mpi4py communicator: the lights are split over its ranks (every
                    rank makes the same call), rank 0 gathers them and writes `out`; rank 0 gets
                    the BrdfTable (equal bit for bit to one process's), the other ranks None
    Returns a BrdfTable; each entry equals wavebrdf.render(heightfield, query with that light,
    resolution, precision) rounded to float32. Ctrl-C stops it (KeyboardInterrupt).
    """
    if isinstance(heightfield, os.PathLike):
        heightfield = os.fspath(heightfield)
    table = _core._render_table(heightfield, query, lights, max_light_sin, resolution, precision,
                                max_memory_gb, "" if out is None else str(out), path, tolerance, comm)
    return None if table is None else BrdfTable(table)


def _lobe_alphas(alpha, alpha_x, alpha_y):
    return (alpha if alpha_x is None else alpha_x, alpha if alpha_y is None else alpha_y)


def lobe_table(distribution="ggx", alpha=0.2, *, alpha_x=None, alpha_y=None, fresnel_f0=1.0, lights=(32, 32),
               max_light_sin=0.9, resolution=64, lambda_um=0.5, max_memory_gb=0.0, out=None):
    """An analytic microfacet lobe as a BRDF table (``wavebrdf lobe``, docs/table.md "Analytic
    lobes"): the Cook-Torrance BRDF with a GGX or Beckmann distribution, height-correlated Smith
    masking-shadowing and Schlick's Fresnel, sampled at the table's light grid and slice pixels.

    distribution    'ggx' or 'beckmann'
    alpha           roughness of an isotropic lobe, 0.001...4 (default 0.2)
    alpha_x, alpha_y  roughness along x (slice rows) and y (columns); default alpha
    fresnel_f0      Schlick's F0, 0...1; 1 (default): no Fresnel, a perfect reflector as the
                    wave-optical models are
    lights, max_light_sin, resolution   the light grid and slice size, as render_table's
    lambda_um       the wavelength recorded in the table (the lobe does not depend on it)
    max_memory_gb   refuse (MemoryError) a table beyond this many GB; 0: the physical memory
    out             optional path: also write the table file there (atomically)
    Returns a BrdfTable (its ``source`` names the lobe); ValueError for a bad value.
    """
    ax, ay = _lobe_alphas(alpha, alpha_x, alpha_y)
    return BrdfTable(_core._lobe_table(str(distribution), float(ax), float(ay), float(fresnel_f0), lights,
                                       float(max_light_sin), int(resolution), float(lambda_um), float(max_memory_gb),
                                       "" if out is None else str(out)))


def lobe_brdf(omega_i, omega_o, distribution="ggx", alpha=0.2, *, alpha_x=None, alpha_y=None, fresnel_f0=1.0):
    """f_r in 1/sr of the lobe lobe_table tabulates, for projected directions omega_i = (x, y)
    (towards the light) and omega_o (towards the viewer); 0 outside the unit disk."""
    ax, ay = _lobe_alphas(alpha, alpha_x, alpha_y)
    return _core._lobe_brdf(str(distribution), float(ax), float(ay), float(fresnel_f0), float(omega_i[0]),
                            float(omega_i[1]), float(omega_o[0]), float(omega_o[1]))
