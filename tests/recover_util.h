#pragma once
// Fixtures shared by the recovery tests: the small isotropic test surface, slices made by the field
// model itself, and the distance of two fields up to a global phase.
#include <algorithm>
#include <cmath>
#include <complex>
#include <cstdint>
#include <vector>

#include <random>

#include "test_util.h"
#include "wavebrdf/constants.h"
#include "wavebrdf/generate.h"
#include "wavebrdf/heightfield.h"
#include "wavebrdf/observation.h"
#include "wavebrdf/recover.h"

namespace wavebrdf::test {

// A rows × rows isotropic surface of 2 µm texels (Gaussian correlation `correlation_um`, seeded),
// scaled so that max |H| = peak_um (texel units, vscale 1).
inline Heightfield peak_scaled_surface(int rows, double correlation_um, double peak_um, std::uint64_t seed) {
    SurfaceParams p;
    p.rows = p.cols = rows;
    p.texel_um = 2.0;
    p.correlation_um = correlation_um;
    p.rms_height_um = 1.0;
    p.seed = seed;
    const Heightfield raw = generate_heightfield(p);
    double peak = 0.0;
    for (double v : raw.values()) peak = std::max(peak, std::abs(v));
    std::vector<double> v = raw.values();
    for (double& x : v) x *= peak_um / (peak * p.texel_um);
    return raw.with_values(v);
}

// A fresh isotropic 12² tile of 2 µm texels (correlation 4 texels, max |H| 0.5 µm: 2-4 rad per
// texel at 0.5 µm) seen by 6 × 6 footprints of σ_p 3 µm, 4 µm apart (linear overlap 1 − 4/18 =
// 78 %) with centres jittered by ±0.2 of a step, at 0.5 and 0.6 µm, 64² pixels each.
struct SmallCase {
    Heightfield truth;
    std::vector<Observation> observations;
};

// The small case's footprints without references: `resolution`² pixels each (seeded by `seed`
// as small_case's).
inline std::vector<Observation> small_case_footprints(std::uint64_t seed, int resolution) {
    std::vector<Observation> observations;
    std::mt19937_64 rng(seed + 100);
    std::uniform_real_distribution<double> jitter(-0.2, 0.2);
    const double step = 4.0;
    for (double lambda : {0.5, 0.6})
        for (int a = 0; a < 6; ++a)
            for (int b = 0; b < 6; ++b) {
                Observation o;
                o.query = make_query(Model::OHS, (a + 0.5 + jitter(rng)) * step, (b + 0.5 + jitter(rng)) * step, 3.0);
                o.lambdas_um = std::vector<double>(1, lambda);  // not = {lambda}: GCC 12's -Wnonnull misfires on it
                o.resolution = resolution;
                observations.push_back(std::move(o));
            }
    return observations;
}

inline SmallCase small_case(std::uint64_t seed) {
    SmallCase c{peak_scaled_surface(12, 8.0, 0.5, seed), small_case_footprints(seed, 64)};
    for (Observation& o : c.observations) o.reference = to_reference(render_observation(c.truth, o));
    return c;
}

// The zero-slope field e^{−i(4π/λ)H} of the heights at the texel centres.
inline std::vector<std::complex<double>> object_of(const Heightfield& hf, double lambda_um) {
    std::vector<std::complex<double>> o(hf.values().size());
    for (int i = 0; i < hf.rows(); ++i)
        for (int j = 0; j < hf.cols(); ++j)
            o[hf.index(i, j)] = std::polar(1.0, -4.0 * k_pi / lambda_um * hf.height_um(i, j));
    return o;
}

// RMS of a − e^{iφ}b over RMS of a, for the best single phase φ.
inline double distance_up_to_phase(const std::vector<std::complex<double>>& a,
                                   const std::vector<std::complex<double>>& b) {
    std::complex<double> overlap = 0.0;
    double norm = 0.0;
    for (std::size_t k = 0; k < a.size(); ++k) {
        overlap += std::conj(b[k]) * a[k];
        norm += std::norm(a[k]);
    }
    const std::complex<double> phase = std::polar(1.0, std::arg(overlap));
    double d = 0.0;
    for (std::size_t k = 0; k < a.size(); ++k) d += std::norm(a[k] - phase * b[k]);
    return std::sqrt(d / norm);
}

// OHS slices made by the field model of the whole (periodic) surface from a known object, on a
// raster of positions `step_um` apart jittered by ±0.15 steps (drawn with `seed`).
inline std::vector<Observation> model_observations(const std::vector<std::complex<double>>& object, int rows, int cols,
                                                   double texel_um, double lambda_um, int n, double sigma_p_um,
                                                   double step_um, std::uint64_t seed) {
    std::vector<Observation> out;
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> jitter(-0.15, 0.15);
    for (double x = 0.5 * step_um; x < rows * texel_um; x += step_um)
        for (double y = 0.5 * step_um; y < cols * texel_um; y += step_um) {
            Observation o;
            o.query = make_query(Model::OHS, x + jitter(rng) * step_um, y + jitter(rng) * step_um, sigma_p_um);
            o.lambdas_um.assign(1, lambda_um);
            o.resolution = n;
            const FieldOperator op(rows, cols, texel_um, o.query, lambda_um, n);
            const auto field = op.forward(object);
            o.reference.resize(field.size());
            for (std::size_t p = 0; p < field.size(); ++p)
                o.reference[p] = float(std::pow(op.amplitude_factor()[p], 2) * std::norm(field[p]));
            out.push_back(std::move(o));
        }
    return out;
}

}  // namespace wavebrdf::test
