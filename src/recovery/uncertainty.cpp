// Error bars of a recovered heightfield: the diagonal of the inverse Gauss–Newton matrix of
// the refinement's loss, by coloured probes and conjugate gradients (uncertainty.h).
#include "wavebrdf/uncertainty.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "core/cholesky.h"
#include "core/exact_sum.h"
#include "core/parallel.h"
#include "core/random.h"
#include "recovery/observation_loss.h"
#include "wavebrdf/constants.h"
#include "wavebrdf/gabor.h"
#include "wavebrdf/memory.h"
#include "wavebrdf/slice_plan.h"
#include "wavebrdf/text.h"

namespace wavebrdf {

namespace {

// Fraction bits of the exact sums of G·v: the products are normalised (max |v| = 1, weights
// scaled to about 1 per slice value), so their terms are far below 2^64 and far above 2^−40.
constexpr int k_product_fraction_bits = 40;

double mean_of(const std::vector<double>& v) {
    double s = 0.0;
    for (double x : v) s += x;
    return v.empty() ? 0.0 : s / double(v.size());
}

void remove_mean(std::vector<double>& v) {
    const double m = mean_of(v);
    for (double& x : v) x -= m;
}

double dot(const std::vector<double>& a, const std::vector<double>& b) {
    double s = 0.0;
    for (std::size_t k = 0; k < a.size(); ++k) s += a[k] * b[k];
    return s;
}

// The stored offset of b − a ≡ d (mod size, 0 … size − 1) along one axis of a band.
int band_offset(int d, int size, int extent, bool full) {
    if (full) return d;
    if (d > size / 2) d -= size;
    return d + extent - 1;
}

}  // namespace

struct GaussNewtonOperator::Impl {
    const std::vector<Observation>* observations = nullptr;
    const Communicator* comm = nullptr;
    int rows = 0, cols = 0;
    double to_um = 1.0;           // raw height value → µm (vscale · texel_um)
    double step_raw = 0.0;        // forward-difference step, raw units
    std::vector<double> heights;  // raw values at the solution
    Heightfield flat{1, 1, std::vector<double>{0.0}};
    std::vector<std::unique_ptr<SlicePlan<double>>> plans;
    std::vector<std::vector<int>> box_rows, box_cols;
    std::vector<std::vector<double>> slices;   // f at the solution, per observation
    std::vector<std::vector<double>> weights;  // W / scale per slice value
    double scale = 1.0;                        // G = scale · (the normalised G)
    double variance = 1.0, dof = 0.0;

    // The normalised G · v for raw vectors (max |v| ≤ 1 each), summed exactly over all ranks.
    std::vector<std::vector<double>> apply_normalised(const std::vector<std::vector<double>>& vectors) const {
        const std::size_t n = std::size_t(rows) * std::size_t(cols), count = vectors.size();
        std::vector<std::vector<double>> out(count);
        if (count == 0) return out;
        detail::ExactParallelSum sum(n * count, k_product_fraction_bits);
        std::vector<double> all;
        sum.run(observations->size(), *comm, all, [&](std::size_t i, detail::ExactScratch& scratch) {
            SlicePlan<double>& plan = *plans[i];
            const std::vector<double>& f0 = slices[i];
            const std::vector<double>& w = weights[i];
            std::vector<double> h(n), jv(f0.size()), gradient(n, 0.0);
            std::vector<int> rows_all;
            double* out_scratch = scratch.data();
            for (std::size_t k = 0; k < count; ++k) {
                for (std::size_t t = 0; t < n; ++t) h[t] = heights[t] + step_raw * vectors[k][t];
                plan.set_heights(h);
                const std::vector<double>& f = plan.forward();
                for (std::size_t p = 0; p < f0.size(); ++p) jv[p] = w[p] * ((f[p] - f0[p]) / step_raw);
                plan.adjoint(jv, gradient);
                for (int r : box_rows[i]) {
                    for (int c : box_cols[i]) {
                        const std::size_t at = std::size_t(r) * std::size_t(cols) + std::size_t(c);
                        out_scratch[k * n + at] += gradient[at];
                        gradient[at] = 0.0;
                    }
                    rows_all.push_back(r + int(k) * rows);
                }
            }
            plan.release();
            std::sort(rows_all.begin(), rows_all.end());
            scratch.take_box(rows_all, box_cols[i], std::size_t(cols));
            return 0.0;
        });
        for (std::size_t k = 0; k < count; ++k)
            out[k].assign(all.begin() + std::ptrdiff_t(k * n), all.begin() + std::ptrdiff_t((k + 1) * n));
        return out;
    }

    // The box texels observation i's slice depends on: those one adjoint (weights 1 … 2, fixed)
    // writes; the others (the box's corners outside the footprint's kernels and their
    // neighbours) have J = 0 and need no forward. Leaves the plan at the solution's heights.
    std::vector<std::size_t> box_texels(std::size_t i) const {
        SlicePlan<double>& plan = *plans[i];
        const std::size_t values = slices[i].size();
        plan.set_heights(heights);
        plan.forward();
        std::vector<double> probe(values), touched(heights.size(), 0.0);
        for (std::size_t p = 0; p < values; ++p) probe[p] = 1.0 + double((p * 2654435761u) % 1024) / 1024.0;
        plan.adjoint(probe, touched);
        std::vector<std::size_t> texels;
        for (int r : box_rows[i])
            for (int c : box_cols[i]) {
                const std::size_t t = std::size_t(r) * std::size_t(cols) + std::size_t(c);
                if (touched[t] != 0.0) texels.push_back(t);
            }
        return texels;
    }

    // Observation i's forward differences, one per box texel its slice depends on (box_texels):
    // column(b, f) gets texel texels[b]'s slice f with that texel raised by step_raw, the others
    // at the solution (the difference quotient is (f − slices[i]) / step_raw). Releases the plan.
    // Returns the forwards run: one per texel and box_texels' one at the solution.
    template <class Column>
    int forward_differences(std::size_t i, const std::vector<std::size_t>& texels, Column&& column) const {
        SlicePlan<double>& plan = *plans[i];
        std::vector<double> h = heights;
        for (std::size_t b = 0; b < texels.size(); ++b) {
            h[texels[b]] = heights[texels[b]] + step_raw;
            plan.set_heights(h);
            column(b, plan.forward());
            h[texels[b]] = heights[texels[b]];
        }
        plan.release();
        return int(texels.size()) + 1;
    }

    // Runs observe(i, scratch) (the forwards it ran) on every observation of this rank into
    // `sum`, a failure on one rank agreed; returns the forwards over all ranks, and sums `sum`
    // over the ranks.
    template <class Observe>
    std::int64_t over_observations(detail::ExactParallelSum& sum, Observe&& observe) const {
        std::vector<int> counted(plans.size(), 0);
        run_agreed(*comm, [&] {
            sum.run_local(plans.size(), [&](std::size_t i, detail::ExactScratch& scratch) {
                counted[i] = observe(i, scratch);
                return 0.0;
            });
        });
        std::vector<double> total_forwards{0.0};
        for (int c : counted) total_forwards[0] += double(c);
        comm->allreduce_sum(total_forwards);
        sum.total().allreduce(*comm);
        return std::int64_t(total_forwards[0]);
    }

    // G's diagonal alone (normalised, raw units): the forward differences of form_band, each
    // column only dotted with itself (no Jacobian kept, no products between columns), exact
    // sums over the observations and the ranks.
    std::vector<double> form_diagonal(std::int64_t& forwards) const {
        const std::size_t n = std::size_t(rows) * std::size_t(cols);
        detail::ExactParallelSum sum(n, k_product_fraction_bits);
        forwards = over_observations(sum, [&](std::size_t i, detail::ExactScratch& scratch) {
            const std::vector<double>& f0 = slices[i];
            const std::vector<double>& w = weights[i];
            const std::vector<std::size_t> texels = box_texels(i);
            double* out = scratch.data();
            const int counted = forward_differences(i, texels, [&](std::size_t b, const std::vector<double>& f) {
                double g = 0.0;
                for (std::size_t p = 0; p < f0.size(); ++p) {
                    const double d = (f[p] - f0[p]) / step_raw;
                    g += w[p] * d * d;
                }
                out[texels[b]] += g;
            });
            scratch.take_box(box_rows[i], box_cols[i], std::size_t(cols));
            return counted;
        });
        std::vector<double> diagonal(n);
        sum.total().take_values(diagonal.data(), n);
        return diagonal;
    }

    // G formed (normalised, raw units; GaussNewtonOperator::band scales it): J of one observation
    // by one forward difference per texel of its box (its columns), then Jᵀ W J over its slice
    // values, exact sums over the observations and the ranks.
    GaussNewtonBand form_band() const {
        GaussNewtonBand band;
        band.rows = rows;
        band.cols = cols;
        // The largest box extents over all ranks' observations (one-hot counts summed).
        std::vector<double> extents(std::size_t(rows + cols + 2), 0.0);
        for (std::size_t i = 0; i < plans.size(); ++i) {
            extents[box_rows[i].size()] += 1.0;
            extents[std::size_t(rows) + 1 + box_cols[i].size()] += 1.0;
        }
        comm->allreduce_sum(extents);
        for (int e = 0; e <= rows; ++e)
            if (extents[std::size_t(e)] > 0.0) band.extent_rows = e;
        for (int e = 0; e <= cols; ++e)
            if (extents[std::size_t(rows) + 1 + std::size_t(e)] > 0.0) band.extent_cols = e;
        band.full_rows = 2 * band.extent_rows - 1 >= rows;
        band.full_cols = 2 * band.extent_cols - 1 >= cols;
        band.offset_rows = band.full_rows ? rows : std::max(1, 2 * band.extent_rows - 1);
        band.offset_cols = band.full_cols ? cols : std::max(1, 2 * band.extent_cols - 1);
        const std::size_t n = std::size_t(rows) * std::size_t(cols), width = band.width();
        const double bytes = double(n) * double(width) * (16.0 + 8.0 * (1 + omp_get_max_threads()));
        detail::ExactParallelSum sum = allocating("the Gauss-Newton band", bytes, [&] {
            return detail::ExactParallelSum(n * width, k_product_fraction_bits);
        });
        band.forwards = over_observations(sum, [&](std::size_t i, detail::ExactScratch& scratch) {
            const std::vector<double>& f0 = slices[i];
            const std::vector<double>& w = weights[i];
            const std::vector<std::size_t> texels = box_texels(i);
            std::vector<std::size_t> pixels;  // the slice values with a weight
            for (std::size_t p = 0; p < f0.size(); ++p)
                if (w[p] > 0.0) pixels.push_back(p);
            const std::size_t b_count = texels.size(), m = pixels.size();
            std::vector<double> a = allocating("an observation's Jacobian", 8.0 * double(b_count) * double(m),
                                               [&] { return std::vector<double>(b_count * m); });
            // √W · J, one column per box texel.
            const int counted = forward_differences(i, texels, [&](std::size_t b, const std::vector<double>& f) {
                double* row = a.data() + b * m;
                for (std::size_t q = 0; q < m; ++q)
                    row[q] = std::sqrt(w[pixels[q]]) * ((f[pixels[q]] - f0[pixels[q]]) / step_raw);
            });
            double* out = scratch.data();
            for (std::size_t x = 0; x < b_count; ++x) {
                const int rx = int(texels[x] / std::size_t(cols)), cx = int(texels[x] % std::size_t(cols));
                const double* ax = a.data() + x * m;
                for (std::size_t y = x; y < b_count; ++y) {
                    const double* ay = a.data() + y * m;
                    double g = 0.0;  // vectorised: a fixed order per build, the same on every rank
#pragma omp simd reduction(+ : g)
                    for (std::size_t q = 0; q < m; ++q) g += ax[q] * ay[q];
                    const int ry = int(texels[y] / std::size_t(cols)), cy = int(texels[y] % std::size_t(cols));
                    const int dr = (ry - rx + rows) % rows, dc = (cy - cx + cols) % cols;
                    out[texels[x] * width +
                        std::size_t(band_offset(dr, rows, band.extent_rows, band.full_rows)) *
                            std::size_t(band.offset_cols) +
                        std::size_t(band_offset(dc, cols, band.extent_cols, band.full_cols))] += g;
                    if (y == x) continue;
                    out[texels[y] * width +
                        std::size_t(band_offset((rows - dr) % rows, rows, band.extent_rows, band.full_rows)) *
                            std::size_t(band.offset_cols) +
                        std::size_t(band_offset((cols - dc) % cols, cols, band.extent_cols, band.full_cols))] += g;
                }
            }
            scratch.take_box(box_rows[i], box_cols[i], std::size_t(cols), int(width));
            return counted;
        });
        band.values.resize(n * width);
        sum.total().take_values(band.values.data(), n * width);
        return band;
    }
};

GaussNewtonOperator::GaussNewtonOperator(const std::vector<Observation>& observations, const Heightfield& estimate,
                                         const Loss& loss, double step_um, const Communicator& comm)
    : m_impl(std::make_unique<Impl>()) {
    Impl& m = *m_impl;
    if (!(step_um > 0.0) || !std::isfinite(step_um))
        throw std::domain_error("height uncertainty: step " + std::to_string(step_um) + " um is invalid; expected > 0");
    if (estimate.vscale() == 0.0)
        throw std::domain_error("height uncertainty: vscale 0 maps every height to 0; expected != 0");
    m.observations = &observations;
    m.comm = &comm;
    m.rows = estimate.rows();
    m.cols = estimate.cols();
    m.to_um = estimate.vscale() * estimate.texel_um();
    m.step_raw = step_um / std::abs(m.to_um);
    m.heights = estimate.values();
    m.flat = estimate.with_values(std::vector<double>(m.heights.size(), 0.0));
    run_agreed(comm, [&] {
        for (std::size_t i = 0; i < observations.size(); ++i) validate(observations[i], i);
        for (const Observation& o : observations)
            validate_footprint(o.query.sigma_p_um, m.flat.period_x_um(), m.flat.period_y_um());
    });
    std::vector<double> total{double(observations.size())};
    comm.allreduce_sum(total);
    if (total[0] == 0.0) throw std::invalid_argument("height uncertainty: no observations given");

    const std::size_t count = observations.size();
    m.plans.resize(count);
    m.box_rows.resize(count);
    m.box_cols.resize(count);
    m.slices.resize(count);
    m.weights.resize(count);
    // The slices at the solution, the residuals in the loss's variable and the values counted.
    // `rounding`: what the references' float storage alone leaves in the residual (a bound of
    // the square of half an ulp per value, in the loss's variable).
    std::vector<double> residual(count, 0.0), values(count, 0.0), curvature(count, 0.0), rounding(count, 0.0);
    const bool poisson = loss.kind == LossKind::Poisson;
    if (poisson && !(loss.photons > 0.0 && std::isfinite(loss.photons)))
        throw std::domain_error("height uncertainty: poisson photons " + std::to_string(loss.photons) +
                                " is invalid; expected > 0");
    detail::ExactParallelSum pass(0);
    std::vector<double> none;
    run_agreed(comm, [&] {  // rank-local work: a failure on one rank is agreed
        pass.run_local(count, [&](std::size_t i, detail::ExactScratch&) {
            const Observation& o = observations[i];
            m.plans[i] = std::make_unique<SlicePlan<double>>(m.flat, detail::calibrated_query(o, 1.0), o.lambdas_um,
                                                             o.resolution, o.channels());
            SlicePlan<double>& plan = *m.plans[i];
            plan.gradient_box(m.box_rows[i], m.box_cols[i]);
            plan.set_heights(m.heights);
            m.slices[i] = plan.forward();
            plan.release();
            const std::vector<double>& f = m.slices[i];
            const std::vector<float>& r = o.reference;
            std::vector<double>& w = m.weights[i];
            w.assign(f.size(), 0.0);
            double s = 0.0;
            if (poisson) {
                double total_r = 0.0;  // over the counted values (as the weighted Poisson loss's)
                for (std::size_t p = 0; p < r.size(); ++p)
                    if (detail::value_weight(o, p) != 0.0) total_r += double(r[p]);
                if (!(total_r > 0.0))
                    throw std::invalid_argument("height uncertainty: observation " + std::to_string(i) +
                                                "'s reference sums to " + std::to_string(total_r) +
                                                "; the poisson loss needs photons");
                s = loss.photons / total_r;
            }
            for (std::size_t p = 0; p < f.size(); ++p) {
                // A value of weight 0 is no measurement (it may hold anything); the others count
                // with their weight in W, the residual and the curvature.
                const double pw = detail::value_weight(o, p);
                if (pw == 0.0) continue;
                const double fi = std::max(f[p], 0.0), ri = std::max(double(r[p]), 0.0);
                if (fi == 0.0 && ri == 0.0 && !poisson) continue;
                double d = 0.0, ulp = 0.0;
                constexpr double half_ulp = 0x1p-24;  // float's relative rounding
                switch (loss.kind) {
                    case LossKind::Poisson:
                        // Fisher information of counts k ~ Poisson(s·I) in I (the loss's 1e-9 counts
                        // keep it finite where I = 0; J vanishes there too).
                        w[p] = s * s / (s * fi + 1e-9);
                        break;
                    case LossKind::Amplitude:
                        d = std::sqrt(fi) - std::sqrt(ri);
                        ulp = half_ulp * std::sqrt(ri);
                        w[p] = 1.0 / (4.0 * (fi + 1e-30));
                        break;
                    case LossKind::MSE:
                        d = fi - ri;
                        ulp = half_ulp * ri;
                        w[p] = 1.0;
                        break;
                    case LossKind::CMSLE:
                        d = std::log(fi + loss.epsilon) - std::log(ri + loss.epsilon);
                        ulp = half_ulp * ri / (ri + loss.epsilon);
                        w[p] = 1.0 / ((fi + loss.epsilon) * (fi + loss.epsilon));
                        break;
                }
                w[p] *= pw;
                residual[i] += pw * d * d;
                rounding[i] += pw * ulp * ulp;
                values[i] += 1.0;
                curvature[i] += w[p] * fi * fi;
            }
            return 0.0;
        });
    });
    const double sum_values = detail::exact_total(values, comm);
    const double sum_curvature = detail::exact_total(curvature, comm);
    if (!poisson) {
        const double sum_residual = detail::exact_total(residual, comm);
        m.dof = sum_values - double(m.heights.size() - 1);
        if (!(m.dof > 0.0))
            throw std::invalid_argument("height uncertainty: " + std::to_string(sum_values) + " slice values for " +
                                        std::to_string(m.heights.size()) +
                                        " heights leave no degree of freedom to estimate the noise from");
        m.variance = sum_residual / m.dof;
        // Noiseless slices fitted exactly leave only the references' float rounding.
        const double rounding_variance = detail::exact_total(rounding, comm) / m.dof;
        if (!(m.variance > 4.0 * rounding_variance) || !std::isfinite(m.variance))
            throw std::domain_error(
                "height uncertainty: the residual variance is " + format_shortest(m.variance) +
                ", at most 4 times what the references' float rounding leaves (" + format_shortest(rounding_variance) +
                "); expected noisy slices (noiseless slices have no error bars under loss " + to_string(loss) + ")");
    }
    // Normalised weights: about 1 per slice value (W f² on average), the variance divided out.
    m.scale = sum_curvature > 0.0 && sum_values > 0.0 ? sum_curvature / sum_values / m.variance : 1.0;
    const double divide = m.scale * m.variance;
    for (std::vector<double>& w : m.weights)
        for (double& x : w) x /= divide;
}

GaussNewtonOperator::~GaussNewtonOperator() = default;
GaussNewtonOperator::GaussNewtonOperator(GaussNewtonOperator&&) noexcept = default;
GaussNewtonOperator& GaussNewtonOperator::operator=(GaussNewtonOperator&&) noexcept = default;

std::vector<std::vector<double>> GaussNewtonOperator::apply(const std::vector<std::vector<double>>& vectors) const {
    const Impl& m = *m_impl;
    const std::size_t n = m.heights.size();
    std::vector<std::vector<double>> raw(vectors.size());
    std::vector<double> norms(vectors.size(), 0.0);
    for (std::size_t k = 0; k < vectors.size(); ++k) {
        if (vectors[k].size() != n)
            throw std::invalid_argument("GaussNewtonOperator::apply: vector " + std::to_string(k) + " has " +
                                        std::to_string(vectors[k].size()) + " values; expected " + std::to_string(n));
        for (double x : vectors[k]) norms[k] = std::max(norms[k], std::abs(x));
        raw[k].resize(n);
        for (std::size_t t = 0; t < n; ++t) raw[k][t] = norms[k] > 0.0 ? vectors[k][t] / norms[k] : 0.0;
    }
    std::vector<std::vector<double>> out = m.apply_normalised(raw);
    // G_µm v_µm = G_raw v_raw / to_um with v_raw = v_µm / to_um; G_raw = scale · normalised.
    for (std::size_t k = 0; k < out.size(); ++k)
        for (double& x : out[k]) x *= m.scale * norms[k] / (m.to_um * m.to_um);
    return out;
}

double GaussNewtonOperator::noise_variance() const { return m_impl->variance; }
double GaussNewtonOperator::degrees_of_freedom() const { return m_impl->dof; }
int GaussNewtonOperator::rows() const { return m_impl->rows; }
int GaussNewtonOperator::cols() const { return m_impl->cols; }

GaussNewtonBand GaussNewtonOperator::band() const {
    const Impl& m = *m_impl;
    GaussNewtonBand band = m.form_band();
    const double to = m.scale / (m.to_um * m.to_um);  // normalised raw units → 1/µm²
    for (double& x : band.values) x *= to;
    return band;
}

std::vector<double> GaussNewtonOperator::diagonal(std::int64_t* forwards) const {
    const Impl& m = *m_impl;
    std::int64_t count = 0;
    std::vector<double> d = m.form_diagonal(count);
    if (forwards) *forwards = count;
    const double to = m.scale / (m.to_um * m.to_um);  // normalised raw units → 1/µm²
    for (double& x : d) x *= to;
    return d;
}

double fisher_rms_error_lower_bound_um(const std::vector<double>& fisher_diagonal) {
    const std::size_t n = fisher_diagonal.size();
    if (n < 2) return 0.0;
    // Var(h_i − mean h) = uᵀ G⁺ u with u = e_i − 1/n, and G·1 = 0 gives uᵀ G u = G_ii, so
    // Cauchy–Schwarz bounds uᵀ G⁺ u ≥ (uᵀu)² / (uᵀ G u) = (1 − 1/n)² / G_ii.
    const double keep = (1.0 - 1.0 / double(n)) * (1.0 - 1.0 / double(n));
    double sum = 0.0;
    for (const double g : fisher_diagonal) {
        if (!(g > 0.0) || !std::isfinite(g)) return HUGE_VAL;  // a texel no slice value depends on
        sum += keep / g;
    }
    return std::sqrt(sum / double(n));
}

std::vector<double> GaussNewtonBand::multiply(const std::vector<double>& v) const {
    const std::size_t n = std::size_t(rows) * std::size_t(cols), w = width();
    if (v.size() != n)
        throw std::invalid_argument("GaussNewtonBand::multiply: " + std::to_string(v.size()) + " values; expected " +
                                    std::to_string(n));
    std::vector<double> out(n, 0.0);
    const int lo_r = full_rows ? 0 : -(extent_rows - 1), lo_c = full_cols ? 0 : -(extent_cols - 1);
    const bool parallel = detail::worth_parallel(static_cast<long long>(double(n) * double(w)));
#pragma omp parallel for schedule(static) if (parallel)
    for (int r = 0; r < rows; ++r)
        for (int c = 0; c < cols; ++c) {
            const std::size_t a = std::size_t(r) * std::size_t(cols) + std::size_t(c);
            const double* g = values.data() + a * w;
            double sum = 0.0;
            for (int i = 0; i < offset_rows; ++i) {
                const std::size_t rb = std::size_t(((r + lo_r + i) % rows + rows) % rows) * std::size_t(cols);
                for (int j = 0; j < offset_cols; ++j)
                    sum += g[std::size_t(i) * std::size_t(offset_cols) + std::size_t(j)] *
                           v[rb + std::size_t(((c + lo_c + j) % cols + cols) % cols)];
            }
            out[a] = sum;
        }
    return out;
}

std::vector<double> GaussNewtonBand::dense() const {
    const std::size_t n = std::size_t(rows) * std::size_t(cols), w = width();
    std::vector<double> g = allocating("a dense Gauss-Newton matrix", 8.0 * double(n) * double(n),
                                       [&] { return std::vector<double>(n * n); });
    const int lo_r = full_rows ? 0 : -(extent_rows - 1), lo_c = full_cols ? 0 : -(extent_cols - 1);
    for (int r = 0; r < rows; ++r)
        for (int c = 0; c < cols; ++c) {
            const std::size_t a = std::size_t(r) * std::size_t(cols) + std::size_t(c);
            for (int i = 0; i < offset_rows; ++i)
                for (int j = 0; j < offset_cols; ++j) {
                    const std::size_t b = std::size_t(((r + lo_r + i) % rows + rows) % rows) * std::size_t(cols) +
                                          std::size_t(((c + lo_c + j) % cols + cols) % cols);
                    g[a * n + b] += values[a * w + std::size_t(i) * std::size_t(offset_cols) + std::size_t(j)];
                }
        }
    return g;
}

namespace {

// diag(G⁺) on the mean-free subspace of a dense symmetric G (n², G·1 = 0, positive on the rest):
// A = G + c·11ᵀ/n (c the mean diagonal) is positive definite, A⁻¹ = G⁺ + 11ᵀ/(n c), so
// diag(G⁺)_i = ‖L⁻¹ e_i‖² − 1/(n c) with A = L Lᵀ. Each dot product runs on one thread in a
// fixed order: the same bits for any thread count. Throws std::domain_error when A is not
// positive definite (a direction without curvature: a texel no observation sees).
std::vector<double> dense_pseudo_inverse_diagonal(std::vector<double> g, std::size_t n) {
    double c = 0.0;
    for (std::size_t a = 0; a < n; ++a) c += g[a * n + a];
    c /= double(n);
    if (!(c > 0.0) || !std::isfinite(c))
        throw std::domain_error("height uncertainty: the Gauss-Newton matrix has mean diagonal " + std::to_string(c) +
                                "; expected > 0");
    for (double& x : g) x += c / double(n);
    const bool parallel = detail::worth_parallel(static_cast<long long>(double(n) * double(n) * double(n) / 6.0));
    const std::size_t j = detail::cholesky_in_place(g, n, parallel);
    if (j < n)
        throw std::domain_error("height uncertainty: the Gauss-Newton matrix is singular at texel " + std::to_string(j) +
                                " (pivot " + std::to_string(g[j * n + j]) +
                                "); expected every texel seen by an observation");
    // x = L⁻¹ e_i (zero above i) by forward substitution; diag(A⁻¹)_i = ‖x‖².
    std::vector<double> diag(n, 0.0);
#pragma omp parallel if (parallel)
    {
        std::vector<double> x(n);
#pragma omp for schedule(dynamic, 8)
        for (std::size_t i = 0; i < n; ++i) {
            double norm = 0.0;
            for (std::size_t r = i; r < n; ++r) {
                const double* lr = g.data() + r * n;
                double s = r == i ? 1.0 : 0.0;
                for (std::size_t k = i; k < r; ++k) s -= lr[k] * x[k];
                x[r] = s / lr[r];
                norm += x[r] * x[r];
            }
            diag[i] = norm - 1.0 / (double(n) * c);
        }
    }
    return diag;
}

}  // namespace

HeightUncertainty height_uncertainty(const std::vector<Observation>& observations, const Heightfield& estimate,
                                     const Loss& loss, const UncertaintySettings& settings, const Communicator& comm) {
    const int d = settings.probe_spacing;
    if (d < 1 || d > 16)
        throw std::domain_error("height uncertainty: probe spacing " + std::to_string(d) +
                                " is invalid; expected 1 to 16");
    if (settings.rounds < 1 || settings.rounds > 64)
        throw std::domain_error("height uncertainty: rounds " + std::to_string(settings.rounds) +
                                " is invalid; expected 1 to 64");
    if (!(settings.cg_tolerance > 0.0 && settings.cg_tolerance < 1.0))
        throw std::domain_error("height uncertainty: CG tolerance " + std::to_string(settings.cg_tolerance) +
                                " is invalid; expected 0 < tolerance < 1");
    if (settings.cg_iterations < 1 || settings.cg_iterations > 10000)
        throw std::domain_error("height uncertainty: CG iterations " + std::to_string(settings.cg_iterations) +
                                " is invalid; expected 1 to 10000");
    if (settings.dense_max_texels < 0 || settings.dense_max_texels > 16384)
        throw std::domain_error("height uncertainty: dense_max_texels " + std::to_string(settings.dense_max_texels) +
                                " is invalid; expected 0 to 16384");
    const GaussNewtonOperator op(observations, estimate, loss, settings.step_um, comm);
    const int rows = estimate.rows(), cols = estimate.cols();
    const std::size_t n = std::size_t(rows) * std::size_t(cols);
    const GaussNewtonBand g = op.band();
    HeightUncertainty result;
    result.noise_variance = op.noise_variance();
    result.forwards = g.forwards;
    std::vector<double> diag(n, 0.0);
    int rounds = 1;
    if (n <= std::size_t(settings.dense_max_texels)) {
        result.exact = true;
        if (n > 1) diag = dense_pseudo_inverse_diagonal(g.dense(), n);
    } else {
        rounds = settings.rounds;
        // The probes: colour (i mod d, j mod d) with random signs, `rounds` draws of each colour.
        std::vector<std::vector<double>> z;
        std::mt19937_64 rng(detail::derive_seed(settings.seed, 0x756e63));  // "unc"
        for (int round = 0; round < settings.rounds; ++round)
            for (int a = 0; a < std::min(d, rows); ++a)
                for (int b = 0; b < std::min(d, cols); ++b) {
                    std::vector<double> v(n, 0.0);
                    for (int i = a; i < rows; i += d)
                        for (int j = b; j < cols; j += d) v[std::size_t(i) * cols + j] = (rng() >> 63) ? 1.0 : -1.0;
                    z.push_back(std::move(v));
                }
        const std::size_t probes = z.size();
        // CG on the mean-free subspace, Jacobi-preconditioned (the diagonal of the formed G).
        result.probes = int(probes);
        std::vector<double> inv_diag(n, 1.0);
        {
            const int lo_r = g.full_rows ? 0 : g.extent_rows - 1, lo_c = g.full_cols ? 0 : g.extent_cols - 1;
            const std::size_t self = std::size_t(lo_r) * std::size_t(g.offset_cols) + std::size_t(lo_c);
            for (std::size_t t = 0; t < n; ++t) {
                const double gt = g.values[t * g.width() + self];
                inv_diag[t] = gt > 0.0 ? 1.0 / gt : 1.0;
            }
        }
        const auto precondition = [&](const std::vector<double>& r) {
            std::vector<double> out(n);
            for (std::size_t t = 0; t < n; ++t) out[t] = inv_diag[t] * r[t];
            remove_mean(out);
            return out;
        };
        std::vector<std::vector<double>> x(probes, std::vector<double>(n, 0.0)), r(probes), p(probes);
        std::vector<double> rz(probes), b_norm(probes), r_norm(probes);
        std::vector<int> iterations(probes, 0);
        std::vector<bool> active(probes, true);
        for (std::size_t k = 0; k < probes; ++k) {
            r[k] = z[k];
            remove_mean(r[k]);
            p[k] = precondition(r[k]);
            rz[k] = dot(r[k], p[k]);
            b_norm[k] = std::sqrt(dot(r[k], r[k]));
            r_norm[k] = b_norm[k];
            if (!(b_norm[k] > 0.0)) active[k] = false;  // a 1×1 tile: nothing to resolve
        }
        for (int it = 0; it < settings.cg_iterations; ++it) {
            bool any = false;
            for (std::size_t k = 0; k < probes; ++k) {
                if (!active[k]) continue;
                any = true;
                std::vector<double> q = g.multiply(p[k]);
                remove_mean(q);  // P G P: the piston is no direction of the solve
                const double pq = dot(p[k], q);
                if (!(pq > 0.0)) {  // no curvature left along p: stop this probe
                    active[k] = false;
                    continue;
                }
                const double alpha = rz[k] / pq;
                for (std::size_t t = 0; t < n; ++t) {
                    x[k][t] += alpha * p[k][t];
                    r[k][t] -= alpha * q[t];
                }
                iterations[k] = it + 1;
                r_norm[k] = std::sqrt(dot(r[k], r[k]));
                if (r_norm[k] <= settings.cg_tolerance * b_norm[k]) {
                    active[k] = false;
                    continue;
                }
                const std::vector<double> zk = precondition(r[k]);
                const double rz_new = dot(r[k], zk);
                const double beta = rz_new / rz[k];
                rz[k] = rz_new;
                for (std::size_t t = 0; t < n; ++t) p[k][t] = zk[t] + beta * p[k][t];
            }
            if (!any) break;
            ++result.products;
        }
        // diag(G⁺)_i ≈ z_i x_i over the probes that hold i, averaged over the rounds.
        for (std::size_t k = 0; k < probes; ++k) {
            result.max_cg_iterations = std::max(result.max_cg_iterations, iterations[k]);
            if (b_norm[k] > 0.0)
                result.worst_relative_residual = std::max(result.worst_relative_residual, r_norm[k] / b_norm[k]);
            for (std::size_t t = 0; t < n; ++t) diag[t] += z[k][t] * x[k][t];
        }
    }
    std::vector<double> filled = diag;
    for (int i = 0; i < rows; ++i)
        for (int j = 0; j < cols; ++j) {
            if (diag[std::size_t(i) * cols + j] > 0.0 || n == 1) continue;
            double sum = 0.0, count = 0.0;
            for (int a = -1; a <= 1; ++a)
                for (int b = -1; b <= 1; ++b) {
                    const double v =
                        diag[std::size_t((i + a + rows) % rows) * cols + std::size_t((j + b + cols) % cols)];
                    if (v > 0.0) {
                        sum += v;
                        count += 1.0;
                    }
                }
            filled[std::size_t(i) * cols + j] = count > 0.0 ? sum / count : 0.0;
            ++result.filled;
        }
    diag = std::move(filled);
    result.sigma_um.resize(n);
    for (std::size_t t = 0; t < n; ++t) result.sigma_um[t] = std::sqrt(std::max(diag[t], 0.0) / rounds);
    return result;
}

namespace {

// The estimate's error at every texel (µm, row-major), each heightfield's mean removed.
std::vector<double> mean_free_errors_um(const Heightfield& estimate, const Heightfield& truth) {
    const int rows = truth.rows(), cols = truth.cols();
    double mean_e = 0.0, mean_t = 0.0;
    for (int i = 0; i < rows; ++i)
        for (int j = 0; j < cols; ++j) {
            mean_e += estimate.height_um(i, j);
            mean_t += truth.height_um(i, j);
        }
    const double n = double(rows) * double(cols);
    mean_e /= n;
    mean_t /= n;
    std::vector<double> errors;
    errors.reserve(std::size_t(rows) * std::size_t(cols));
    for (int i = 0; i < rows; ++i)
        for (int j = 0; j < cols; ++j)
            errors.push_back((estimate.height_um(i, j) - mean_e) - (truth.height_um(i, j) - mean_t));
    return errors;
}

}  // namespace

double error_coverage(const Heightfield& estimate, const Heightfield& truth, const std::vector<double>& sigma_um,
                      double k) {
    if (estimate.rows() != truth.rows() || estimate.cols() != truth.cols() ||
        sigma_um.size() != estimate.values().size())
        throw std::invalid_argument("error_coverage: estimate " + std::to_string(estimate.rows()) + " x " +
                                    std::to_string(estimate.cols()) + ", truth " + std::to_string(truth.rows()) +
                                    " x " + std::to_string(truth.cols()) + " and " + std::to_string(sigma_um.size()) +
                                    " sigmas; expected the same size");
    if (!(k > 0.0)) throw std::domain_error("error_coverage: k " + std::to_string(k) + " is invalid; expected > 0");
    const std::vector<double> errors = mean_free_errors_um(estimate, truth);
    double inside = 0.0;
    for (std::size_t t = 0; t < errors.size(); ++t)
        if (std::abs(errors[t]) <= k * sigma_um[t]) inside += 1.0;
    return inside / double(errors.size());
}

UncertaintyCost predicted_uncertainty_cost(const std::vector<Observation>& observations, const Heightfield& estimate,
                                           double pass_seconds, const UncertaintySettings& settings, int threads) {
    if (!(std::isfinite(pass_seconds) && pass_seconds >= 0.0))
        throw std::domain_error("predicted uncertainty seconds: pass seconds " + std::to_string(pass_seconds) +
                                " is invalid; expected a finite value >= 0");
    const int rows = estimate.rows(), cols = estimate.cols();
    const double n = double(rows) * double(cols), texel = estimate.texel_um();
    const double per_forward = observations.empty() ? 0.0 : pass_seconds / double(observations.size());
    const double rate = k_uncertainty_madds_per_second;
    const double workers = double(std::max(threads, 1));
    UncertaintyCost cost;
    int extent_rows = 1, extent_cols = 1;
    double held = 0.0, jacobian = 0.0, diagonal_madds = 0.0;
    for (const Observation& o : observations) {
        // The texels the slice depends on: the kernels within 3σ_p and their neighbours, a disk
        // of radius 3σ_p + 1 texel (SlicePlan::gradient_box's box holds them).
        const double reach = 3.0 * o.query.sigma_p_um / texel;
        const int er = std::min(rows, 2 * int(std::ceil(reach)) + 3), ec = std::min(cols, 2 * int(std::ceil(reach)) + 3);
        extent_rows = std::max(extent_rows, er);
        extent_cols = std::max(extent_cols, ec);
        const double touched = std::min(double(er) * double(ec), k_pi * (reach + 1.0) * (reach + 1.0));
        const double values = double(o.resolution) * double(o.resolution) * double(o.channels());
        cost.forwards += touched + 2.0;
        cost.product_madds += 0.5 * touched * touched * values;
        diagonal_madds += touched * values;
        // The slice and its weights kept per observation, its plan's bookkeeping (released
        // between uses), and the largest Jacobian one thread holds.
        held += 2.0 * sizeof(double) * values + 2048.0;
        jacobian = std::max(jacobian, double(sizeof(double)) * touched * values);
    }
    const double width = double(2 * extent_rows - 1 >= rows ? rows : 2 * extent_rows - 1) *
                         double(2 * extent_cols - 1 >= cols ? cols : 2 * extent_cols - 1);
    // Forming the band (GaussNewtonOperator::band): the exact sum's accumulator and scratches.
    const double forming = n * width * (16.0 + sizeof(double) * (1.0 + workers)) + workers * jacobian;
    double solving = n * width * sizeof(double);  // the band, kept through the solve
    if (n <= double(settings.dense_max_texels)) {
        // The Cholesky factor (n³/3) and a forward substitution per texel for the diagonal (n³/6).
        cost.solve_madds = n * n * n / 2.0;
        solving += n * n * sizeof(double) + workers * n * sizeof(double);
    } else {
        const double probes = double(std::min(settings.probe_spacing, rows)) *
                              double(std::min(settings.probe_spacing, cols)) * double(settings.rounds);
        cost.solve_madds = probes * double(settings.cg_iterations) * n * width;
        // Per probe (all rounds at once): its signs, x, r and p; the preconditioner and the diagonal.
        solving += (4.0 * probes + 3.0) * n * sizeof(double);
    }
    cost.bytes = held + std::max(forming, solving);
    cost.seconds = k_uncertainty_forward_fraction * cost.forwards * per_forward +
                   cost.product_madds / (k_uncertainty_vector_speedup * rate) + cost.solve_madds / rate;
    cost.diagonal_seconds = k_uncertainty_forward_fraction * cost.forwards * per_forward + diagonal_madds / rate;
    cost.diagonal_bytes = held + n * (16.0 + sizeof(double) * (1.0 + workers));
    return cost;
}

double predicted_uncertainty_seconds(const std::vector<Observation>& observations, const Heightfield& estimate,
                                     double pass_seconds, const UncertaintySettings& settings) {
    return predicted_uncertainty_cost(observations, estimate, pass_seconds, settings, 1).seconds;
}

double median_sigma_um(const std::vector<double>& sigma_um) {
    if (sigma_um.empty()) return 0.0;
    std::vector<double> v = sigma_um;
    const std::size_t mid = v.size() / 2;
    std::nth_element(v.begin(), v.begin() + std::ptrdiff_t(mid), v.end());
    if (v.size() % 2 == 1) return v[mid];
    const double upper = v[mid];
    return 0.5 * (upper + *std::max_element(v.begin(), v.begin() + std::ptrdiff_t(mid)));
}

UncertaintyReport uncertainty_report(HeightUncertainty map, double seconds, const Heightfield& estimate,
                                     const Heightfield* truth) {
    UncertaintyReport r;
    r.seconds = seconds;
    r.median_sigma_um = median_sigma_um(map.sigma_um);
    if (truth) {
        r.coverage_1sigma = error_coverage(estimate, *truth, map.sigma_um, 1.0);
        r.coverage_2sigma = error_coverage(estimate, *truth, map.sigma_um, 2.0);
        const std::vector<double> errors = mean_free_errors_um(estimate, *truth);
        double sum = 0.0;
        for (const double e : errors) sum += e * e;
        r.rms_error_um = std::sqrt(sum / double(errors.size()));
    }
    r.map = std::move(map);
    return r;
}

}  // namespace wavebrdf
