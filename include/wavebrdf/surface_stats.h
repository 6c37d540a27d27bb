#pragma once
// Areal surface texture parameters of ISO 25178-2 and the surface's power spectral density and
// autocorrelation, for measured surfaces (rectangular spacing) and heightfields alike; and the
// one-line unit check every command prints for the heightfield it reads. docs/surfaces.md
// ("Parameters") gives each definition as computed here.
#include <string>
#include <vector>

#include "wavebrdf/heightfield.h"

namespace wavebrdf {

// A grid of heights with its spacing, the input of every function below.
//   rows, cols   points along y and along x, ≥ 2 each (differences need two points)
//   dx_um        spacing along x (between columns), µm, > 0
//   dy_um        spacing along y (between rows), µm, > 0
//   heights_um   rows · cols finite heights in µm, row-major: heights_um[r · cols + c] at
//                x = c · dx_um, y = r · dy_um (NaN refused: fill them first)
struct HeightGrid {
    int rows = 0;
    int cols = 0;
    double dx_um = 1.0;
    double dy_um = 1.0;
    std::vector<double> heights_um;
};

// The heightfield's heights in µm (H = v · w · h) on its square texels, transposed: a
// HeightGrid is an image (rows along y, columns along x, as surface_file.h's MeasuredSurface),
// while the Heightfield's row index runs along x (docs/model.md §2).
HeightGrid height_grid(const Heightfield& heightfield);

// The ISO 25178-2 parameters of a surface, computed over the whole grid as given (no form
// removal or filtering beyond subtracting the mean height: condition the surface first,
// conditioning.h). Definitions in docs/surfaces.md.
struct SurfaceParameters {
    double Sa = 0.0;   // arithmetic mean height, µm
    double Sq = 0.0;   // root mean square height, µm
    double Sp = 0.0;   // maximum peak height above the mean, µm
    double Sv = 0.0;   // maximum pit depth below the mean, µm (positive)
    double Sz = 0.0;   // Sp + Sv, µm
    double Ssk = 0.0;  // skewness (0 for a flat surface)
    double Sku = 0.0;  // kurtosis (0 for a flat surface)
    double Sdq = 0.0;  // root mean square gradient, forward differences (dimensionless)
    double Sdr = 0.0;  // developed interfacial area ratio, % (two triangles per grid cell)
    double Sal = 0.0;  // autocorrelation length: fastest decay of the ACF to 0.2, µm
    double Str = 0.0;  // texture aspect ratio: fastest / slowest decay to 0.2, 0 … 1
    double Std = 0.0;  // texture direction: the lay's angle in degrees, [0, 180), see below
    // Whether the ACF fell to 0.2 within half the grid's extent in every direction: when not
    // (a lay longer than half the grid), the slowest decay is that extent and Str is an upper
    // bound; when it fell nowhere (a surface correlated over the whole grid), Sal is too.
    bool acf_decayed_everywhere = true;
    bool acf_decayed_somewhere = true;
};

// The parameters of `grid`. Std is measured from the x axis towards y, and is the direction
// of the lay (the grooves), i.e. 90° from the direction of the angular power spectrum's
// maximum. A flat surface gives Sq = 0, Ssk =
// Sku = 0, Sal = 0, Str = 1, Std = 0. Throws std::invalid_argument for a grid smaller than
// 2 × 2, larger than 2^24 points, a size mismatch, a spacing ≤ 0 or non-finite, or a
// non-finite height (naming the count of NaN points, which must be filled first).
SurfaceParameters surface_parameters(const HeightGrid& grid);
SurfaceParameters surface_parameters(const Heightfield& heightfield);

// The names and values of `p` in the order of ISO 25178-2, as the JSON keys "Sa", "Sq", …
// (lengths in µm, Sdr in %, Std in degrees).
std::vector<std::pair<std::string, double>> parameter_list(const SurfaceParameters& p);

// The surface's power spectral density, periodic estimate (no window):
//   C(q) = dx dy / (N M) · |Σ_ij z_ij e^{-i (qx x_j + qy y_i)}|²   (µm⁴)
// on the FFT grid qx = 2π kx / (M dx), qy = 2π ky / (N dy) (N rows, M columns), with z the
// heights less their mean.
// Parseval: Σ C Δqx Δqy / (2π)² = Sq². `values` is rows × cols, row-major, the zero frequency
// at (rows / 2, cols / 2) (centred). The radial average bins |q| in steps of
// max(Δqx, Δqy) up to the smaller Nyquist frequency; `q_per_um` is each bin's mean |q|.
struct Spectrum2d {
    int rows = 0;
    int cols = 0;
    // Steps between neighbouring columns (along x) and rows (along y): rad/µm for the PSD,
    // µm for the ACF.
    double step_x = 0.0;
    double step_y = 0.0;
    std::vector<double> values;
};
struct RadialProfile {
    std::vector<double> r;      // bin centres: |q| in rad/µm (PSD) or lag in µm (ACF)
    std::vector<double> value;  // the mean over the bin
    std::vector<int> count;     // points in the bin
};
Spectrum2d power_spectrum_2d(const HeightGrid& grid);
RadialProfile radial_power_spectrum(const HeightGrid& grid);

// The areal autocorrelation function of ISO 25178-2 (heights less their mean), estimated
// without wrapping (zero-padded FFT) and normalised by the number of overlapping points, then
// divided by its value at zero lag (so 1 there; a flat surface gives 1 everywhere). `values` is
// (2 rows − 1) × (2 cols − 1), zero lag at (rows − 1, cols − 1); lag steps dy (rows) and dx
// (columns). The radial average bins the lag in steps of max(dx, dy) up to half the smaller
// extent.
Spectrum2d autocorrelation_2d(const HeightGrid& grid);
RadialProfile radial_autocorrelation(const HeightGrid& grid);

// An estimate's spectrum against a known truth's (a recovery's report, docs/recovery.md "The
// spectrum against the truth's"): the radial PSDs (radial_power_spectrum's bins) of the truth,
// the estimate and their difference (estimate − truth, each less its mean), and the band the
// estimate resolves: up to the first bin where the error's power exceeds the truth's (the error's
// amplitude there larger than the surface's own). Same rows, columns and texel width; throws
// std::invalid_argument otherwise.
struct SpectrumComparison {
    std::vector<double> q_per_um;      // bin centres (mean |q|), rad/µm
    std::vector<double> truth_um4;     // the truth's radial PSD, µm⁴
    std::vector<double> estimate_um4;  // the estimate's
    std::vector<double> error_um4;     // of estimate − truth
    std::vector<int> count;            // FFT points in the bin
    // The largest bin centre up to which every bin has error_um4 ≤ truth_um4 (0: not even the
    // first), and its wavelength 2π / q (µm; infinite when 0). `resolved_all`: every bin up to
    // the smaller Nyquist frequency.
    double resolved_q_per_um = 0.0;
    double resolved_wavelength_um = 0.0;
    bool resolved_all = false;
    // Σ over the bins of error_um4 · count over Σ truth_um4 · count: the error's share of the
    // truth's power (≈ the squared relative rms error over the binned band).
    double error_power_ratio = 0.0;
};
SpectrumComparison compare_spectra(const Heightfield& truth, const Heightfield& estimate);

// What every command that reads or makes a heightfield prints about it: its rms height (µm),
// rms slope (sqrt(mean(s_x² + s_y²) / 2), s by the model's wrapping central differences,
// Heightfield::slope) and the rms of the phase a
// reflection at normal incidence gives at `lambda_um` (4π Sq / λ, radians), and warnings where
// these fall outside what the model is valid for (docs/model.md, "Where the model holds"):
// rms slope above 1; heights whose size suggests nanometres read as µm (rms height above 1 mm,
// or an rms slope that becomes ≤ 1 at a thousandth of the heights) or metres read as µm (rms
// height below 0.1 nm on a surface that is not flat).
struct UnitCheck {
    double rms_height_um = 0.0;
    double rms_slope = 0.0;
    double phase_rms_rad = 0.0;
    double lambda_um = 0.0;
    std::vector<std::string> warnings;  // each one line, without a "warning:" prefix
};
UnitCheck check_units(const HeightGrid& grid, double lambda_um);  // throws as surface_parameters
UnitCheck check_units(const Heightfield& heightfield, double lambda_um);
// The same check over the part of the surface one footprint sees: the texels of its kernels
// (footprint_kernels, gabor.h; slopes from their neighbours as above). What render, genbrdf and
// table print: they read only the footprint's rows of a file, and a slice depends on no other
// texel. Throws as footprint_kernels.
UnitCheck check_units_footprint(const Heightfield& heightfield, double x_um, double y_um, double sigma_p_um,
                                double lambda_um);
// "rms height 0.1234 um, rms slope 0.05678, phase rms 3.102 rad at 0.5 um" (no newline).
std::string describe(const UnitCheck& check);

}  // namespace wavebrdf
