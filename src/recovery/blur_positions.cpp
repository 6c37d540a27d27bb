// The blurred fit with the footprint positions corrected in it (blur_positions.h).
#include "recovery/blur_positions.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <memory>
#include <omp.h>
#include <stdexcept>
#include <string>

#include "core/exact_sum.h"
#include "core/parallel.h"
#include "wavebrdf/constants.h"
#include "wavebrdf/optim.h"
#include "wavebrdf/slice_plan.h"

namespace wavebrdf::detail {

namespace {

// B[p, f] = G_β(u_p − u_f) Δu_f over a slice of n pixels at λ (as recover_blur.cpp's).
Eigen::MatrixXd blur_matrix(int n, double lambda_um, double beta) {
    Eigen::MatrixXd b(n, n);
    const double du = 2.0 / (n * lambda_um);
    const double norm = du / (std::sqrt(2.0 * k_pi) * beta);
    for (int p = 0; p < n; ++p)
        for (int f = 0; f < n; ++f) {
            const double d = (slice_omega(p, n) - slice_omega(f, n)) / lambda_um;
            b(p, f) = norm * std::exp(-0.5 * d * d / (beta * beta));
        }
    return b;
}

// One blur stage's data per observation: its blur matrix (shared by equal n, λ, β) and √(B R Bᵀ).
struct StageData {
    std::vector<Eigen::MatrixXf> matrices;
    std::vector<std::array<double, 3>> keys;  // n, λ, β of each matrix
    std::vector<std::size_t> matrix_of;       // per observation
    std::vector<Eigen::MatrixXd> sqrt_reference;
    std::vector<double> totals;  // Σ B R Bᵀ per observation
};

StageData make_stage(const std::vector<const Observation*>& group, double blur_width) {
    StageData s;
    for (const Observation* o : group) {
        const int n = o->resolution;
        const double lambda = o->lambdas_um[0];
        const double beta = blur_width / (2.0 * std::sqrt(2.0) * k_pi * o->query.sigma_p_um);
        const std::array<double, 3> key{double(n), lambda, beta};
        std::size_t m = 0;
        while (m < s.keys.size() && s.keys[m] != key) ++m;
        Eigen::MatrixXd b = blur_matrix(n, lambda, beta);
        if (m == s.keys.size()) {
            s.keys.push_back(key);
            s.matrices.push_back(b.cast<float>());
        }
        s.matrix_of.push_back(m);
        Eigen::MatrixXd r(n, n);
        for (int p = 0; p < n; ++p)
            for (int q = 0; q < n; ++q) r(p, q) = std::max(double(o->reference[std::size_t(p) * n + q]), 0.0);
        r = b * r * b.transpose();
        s.totals.push_back(r.sum());
        s.sqrt_reference.push_back(r.cwiseSqrt());
    }
    return s;
}

// Σ(√e·√M_b − √R_b)² of the forwarded slice f (n² values) with M_b = B f Bᵀ; with `weights`
// given (n² doubles) it receives scale · ∂/∂f. root_exposure < 0: the closed-form exposure
// √(Σ R_b / Σ M_b) of this slice (for the registration).
double blurred_term(const std::vector<float>& f, const Eigen::MatrixXf& blur, const Eigen::MatrixXd& sqrt_reference,
                    double total, double root_exposure, double scale, std::vector<double>* weights) {
    const int n = int(blur.rows());
    Eigen::MatrixXf m(n, n);
    for (int p = 0; p < n; ++p)
        for (int q = 0; q < n; ++q) m(p, q) = f[std::size_t(p) * n + q];
    m = blur * m * blur.transpose();
    if (root_exposure < 0.0) {
        double model_total = 0.0;
        for (int p = 0; p < n; ++p)
            for (int q = 0; q < n; ++q) model_total += std::max(double(m(p, q)), 0.0);
        root_exposure = model_total > 0.0 ? std::sqrt(total / model_total) : 1.0;
    }
    double v = 0.0;
    Eigen::MatrixXf dm(n, n);
    for (int p = 0; p < n; ++p)
        for (int q = 0; q < n; ++q) {
            const double mpq = double(m(p, q));
            const double a = std::sqrt(std::max(mpq, 0.0) + 1e-300);
            const double diff = root_exposure * a - sqrt_reference(p, q);
            v += diff * diff;
            dm(p, q) = mpq > 0.0 ? float(scale * diff * root_exposure / a) : 0.0f;
        }
    if (weights) {
        const Eigen::MatrixXf w = blur.transpose() * dm * blur;
        weights->resize(std::size_t(n) * n);
        for (int p = 0; p < n; ++p)
            for (int q = 0; q < n; ++q) (*weights)[std::size_t(p) * n + q] = double(w(p, q));
    }
    return v;
}

Query moved(const Observation& o, double dx_um, double dy_um) {
    Query q = o.query;
    q.x_um += dx_um;
    q.y_um += dy_um;
    return q;
}

void check_group(const std::vector<const Observation*>& group, const std::vector<std::size_t>& position,
                 std::size_t offsets) {
    if (position.size() != group.size())
        throw std::invalid_argument("blurred position fit: " + std::to_string(position.size()) +
                                    " position indices for " + std::to_string(group.size()) +
                                    " observations; expected one each");
    for (std::size_t g = 0; g < group.size(); ++g) {
        if (!group[g] || group[g]->lambdas_um.size() != 1 || group[g]->channels() != 1)
            throw std::invalid_argument("blurred position fit: observation " + std::to_string(g) +
                                        " is not a single-wavelength slice");
        if (2 * position[g] + 1 >= offsets)
            throw std::invalid_argument("blurred position fit: position " + std::to_string(position[g]) +
                                        " is outside the " + std::to_string(offsets / 2) + " offsets given");
    }
}

double register_with(const std::vector<const Observation*>& group, const std::vector<std::size_t>& position,
                     const Heightfield& heights, const StageData& stage, bool closed_form_exposure,
                     double radius_texels, double step_texels, std::vector<double>& offsets_um,
                     const Communicator& comm) {
    if (!(radius_texels >= 0.0) || !(step_texels > 0.0) || !(radius_texels / step_texels <= 16.0))
        throw std::invalid_argument("register_positions_blurred: radius " + std::to_string(radius_texels) + " / step " +
                                    std::to_string(step_texels) +
                                    " texels invalid; expected radius >= 0, step > 0, radius/step <= 16");
    const int half = int(std::floor(radius_texels / step_texels + 1e-9));
    const int side = 2 * half + 1;
    const std::size_t candidates = std::size_t(side) * side;
    const std::size_t positions = offsets_um.size() / 2;
    const double texel_um = heights.texel_um();
    std::vector<double> local(group.size() * candidates, 0.0);
    const long long work = (long long)(group.size() * candidates);
#pragma omp parallel for schedule(dynamic) if (work > 1 && !in_parallel_region())
    for (long long k = 0; k < work; ++k) {
        const std::size_t g = std::size_t(k) / candidates, c = std::size_t(k) % candidates;
        const Observation& o = *group[g];
        const std::size_t p = position[g];
        const double dx = offsets_um[2 * p] + texel_um * step_texels * (int(c / side) - half);
        const double dy = offsets_um[2 * p + 1] + texel_um * step_texels * (int(c % side) - half);
        SlicePlan<float> plan(heights, moved(o, dx, dy), o.lambdas_um, o.resolution, 1, {}, false);
        const std::vector<float>& f = plan.forward();
        local[k] = blurred_term(f, stage.matrices[stage.matrix_of[g]], stage.sqrt_reference[g], stage.totals[g],
                                closed_form_exposure ? -1.0 : 1.0, 1.0, nullptr);
    }
    // Per position, every rank's observations (one per position and wavelength: the sum adds
    // zeros to one value on one rank, the same bits for any split).
    std::vector<double> losses(positions * candidates + positions, 0.0);
    for (std::size_t g = 0; g < group.size(); ++g) {
        for (std::size_t c = 0; c < candidates; ++c) losses[position[g] * candidates + c] += local[g * candidates + c];
        losses[positions * candidates + position[g]] += 1.0;
    }
    comm.allreduce_sum(losses);
    double moved_sq = 0.0;
    for (std::size_t p = 0; p < positions; ++p) {
        if (losses[positions * candidates + p] == 0.0) continue;  // no observation here
        std::size_t best = candidates / 2;                        // no shift unless a smaller loss
        for (std::size_t c = 0; c < candidates; ++c)
            if (losses[p * candidates + c] < losses[p * candidates + best]) best = c;
        const double sx = step_texels * (int(best / side) - half), sy = step_texels * (int(best % side) - half);
        offsets_um[2 * p] += texel_um * sx;
        offsets_um[2 * p + 1] += texel_um * sy;
        moved_sq += sx * sx + sy * sy;
    }
    return positions ? std::sqrt(moved_sq / double(2 * positions)) : 0.0;
}

}  // namespace

double register_positions_blurred(const std::vector<const Observation*>& group,
                                  const std::vector<std::size_t>& position, const Heightfield& heights,
                                  double blur_width, double radius_texels, double step_texels,
                                  std::vector<double>& offsets_um, const Communicator& comm) {
    check_group(group, position, offsets_um.size());
    if (!(blur_width > 0.0) || !std::isfinite(blur_width))
        throw std::invalid_argument("register_positions_blurred: blur width " + std::to_string(blur_width) +
                                    " is invalid; expected > 0");
    const StageData stage = make_stage(group, blur_width);
    return register_with(group, position, heights, stage, false, radius_texels, step_texels, offsets_um, comm);
}

Heightfield fit_blurred_with_positions(const std::vector<const Observation*>& group,
                                       const std::vector<std::size_t>& position, const Heightfield& initial,
                                       const BlurredFitSettings& settings, std::vector<double>& offsets_um,
                                       const std::function<bool(int, int, double)>& on_iteration,
                                       const Communicator& comm, const BlurRegistration& registration) {
    check_group(group, position, offsets_um.size());
    if (settings.iterations < 0 || settings.history < 1)
        throw std::domain_error("fit_blurred_with_positions: iterations " + std::to_string(settings.iterations) +
                                " / history " + std::to_string(settings.history) + " invalid; expected >= 0 / >= 1");
    const std::size_t cells = initial.values().size(), count = offsets_um.size() / 2;
    const std::size_t cols = std::size_t(initial.cols());
    const double texel_um = initial.texel_um();
    std::vector<double> x = initial.values();
    x.resize(cells + 2 * count);
    for (std::size_t k = 0; k < 2 * count; ++k) x[cells + k] = offsets_um[k] / texel_um;
    std::vector<std::unique_ptr<SlicePlan<float>>> plans(group.size());
    std::vector<std::array<double, 2>> plan_offset(group.size());
    std::vector<std::vector<int>> box_rows(group.size()), box_cols(group.size());
    std::vector<std::vector<double>> height_scratch(std::size_t(std::max(1, omp_get_max_threads())));
    ExactParallelSum exact_sum(cells + 2 * count);
    const std::vector<int> row0{0};
    const auto plan_for = [&](std::size_t g, const std::vector<double>& v) -> SlicePlan<float>& {
        const std::size_t p = position[g];
        const std::array<double, 2> d{texel_um * v[cells + 2 * p], texel_um * v[cells + 2 * p + 1]};
        if (!plans[g] || plan_offset[g] != d) {
            const Observation& o = *group[g];
            plans[g] = std::make_unique<SlicePlan<float>>(initial, moved(o, d[0], d[1]), o.lambdas_um, o.resolution, 1);
            plans[g]->gradient_box(box_rows[g], box_cols[g]);
            plan_offset[g] = d;
        }
        return *plans[g];
    };
    bool go_on = true;
    for (std::size_t s = 0; s < settings.blur_widths.size() && go_on; ++s) {
        const StageData stage = make_stage(group, settings.blur_widths[s]);
        const double total = exact_total(stage.totals, comm);
        if (!(total > 0.0)) throw std::invalid_argument("fit_blurred_with_positions: every reference slice is zero");
        const double inv_total = 1.0 / total;
        std::vector<double> root_exposures(group.size(), 1.0);
        const auto set_exposures = [&] {
            if (!settings.calibrate_exposure) return;
            for (std::size_t g = 0; g < group.size(); ++g) {
                SlicePlan<float>& plan = plan_for(g, x);
                plan.set_heights(std::vector<double>(x.begin(), x.begin() + std::ptrdiff_t(cells)));
                const std::vector<float>& f = plan.forward();
                std::vector<double> none;
                const int n = group[g]->resolution;
                Eigen::MatrixXf m(n, n);
                for (int p = 0; p < n; ++p)
                    for (int q = 0; q < n; ++q) m(p, q) = f[std::size_t(p) * n + q];
                const Eigen::MatrixXf& b = stage.matrices[stage.matrix_of[g]];
                m = b * m * b.transpose();
                double model_total = 0.0;
                for (int p = 0; p < n; ++p)
                    for (int q = 0; q < n; ++q) model_total += std::max(double(m(p, q)), 0.0);
                plan.release();
                root_exposures[g] = model_total > 0.0 ? std::sqrt(stage.totals[g] / model_total) : 1.0;
            }
        };
        bool joint = false;
        const auto objective = [&](const std::vector<double>& v, std::vector<double>& grad) {
            const std::vector<double> heights(v.begin(), v.begin() + std::ptrdiff_t(cells));
            const double value = exact_sum.run(group.size(), comm, grad, [&](std::size_t g, ExactScratch& scratch) {
                SlicePlan<float>& plan = plan_for(g, v);
                plan.set_heights(heights);
                const std::vector<float>& f = plan.forward();
                std::vector<double> weights;
                const double term = inv_total * blurred_term(f, stage.matrices[stage.matrix_of[g]],
                                                             stage.sqrt_reference[g], stage.totals[g],
                                                             root_exposures[g], inv_total, &weights);
                std::vector<double>& hs = height_scratch[std::size_t(omp_get_thread_num())];
                if (hs.size() != cells) hs.assign(cells, 0.0);
                const std::array<double, 2> gp = plan.adjoint_with_position(weights, hs, 1.0);
                std::vector<double>& out = scratch.vector();
                for (int r : box_rows[g])
                    for (int c : box_cols[g]) {
                        const std::size_t at = std::size_t(r) * cols + std::size_t(c);
                        out[at] = hs[at];
                        hs[at] = 0.0;
                    }
                scratch.take_box(box_rows[g], box_cols[g], cols);
                if (joint) {
                    const std::size_t p = position[g];
                    out[cells + 2 * p] += texel_um * gp[0];  // per texel
                    out[cells + 2 * p + 1] += texel_um * gp[1];
                    scratch.take_box(row0, {int(cells + 2 * p), int(cells + 2 * p + 1)}, 1);
                }
                plan.release();
                return term;
            });
            return value;
        };
        LbfgsOptions lo;
        lo.history = settings.history;
        lo.gradient_tolerance = 0.0;
        int done = 0;
        const auto run = [&](int iterations) {
            if (iterations <= 0 || !go_on) return;
            lo.max_iterations = iterations;
            const int before = done;
            lbfgs_minimize(objective, x, lo, [&](int it, double value) {
                done = before + it;
                if (on_iteration && !on_iteration(int(s), done, value)) go_on = false;
                go_on = !comm.any(!go_on);
                return go_on;
            });
        };
        set_exposures();
        // Heights at the offsets so far, then the registration at those heights, then both.
        joint = false;
        if (int(s) < registration.first_stage) {
            run(settings.iterations);
            continue;
        }
        const bool first = int(s) == registration.first_stage;
        run(settings.iterations / 2);
        if (!go_on) break;
        std::vector<double> off(2 * count);
        for (std::size_t k = 0; k < 2 * count; ++k) off[k] = texel_um * x[cells + k];
        const Heightfield current = initial.with_values(
            std::vector<double>(x.begin(), x.begin() + std::ptrdiff_t(cells)));
        register_with(group, position, current, stage, settings.calibrate_exposure,
                      first ? registration.first_radius_texels : registration.later_radius_texels,
                      first ? registration.first_step_texels : registration.later_step_texels, off, comm);
        for (std::size_t k = 0; k < 2 * count; ++k) x[cells + k] = off[k] / texel_um;
        set_exposures();
        joint = true;
        run(settings.iterations - settings.iterations / 2);
    }
    for (std::size_t k = 0; k < 2 * count; ++k) offsets_um[k] = texel_um * x[cells + k];
    return initial.with_values(std::vector<double>(x.begin(), x.begin() + std::ptrdiff_t(cells)));
}

}  // namespace wavebrdf::detail
