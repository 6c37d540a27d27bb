// The recovery's model check: refinement in the field model and the model selection
// (recover_field_model.h; experiments/2026-11-23-scalar-diffraction-model-check.md).
#include "recovery/recover_field_model.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <complex>
#include <stdexcept>
#include <string>

#include "wavebrdf/constants.h"
#include "wavebrdf/optim.h"
#include "wavebrdf/recover.h"
#include "wavebrdf/slice_plan.h"
#include "core/stall_rule.h"
#include "core/exact_sum.h"
#include "core/parallel.h"
#include "recovery/amplitude_loss.h"
#include "recovery/calibration_detail.h"
#include "recovery/field_operator_detail.h"
#include "recovery/observation_loss.h"

namespace wavebrdf::detail {

namespace {
// Keys' cubic convolution kernel (a = −½) at distance x (texels).
double keys_kernel(double x) {
    x = std::abs(x);
    if (x <= 1.0) return (1.5 * x - 2.5) * x * x + 1.0;
    if (x < 2.0) return ((-0.5 * x + 2.5) * x - 4.0) * x + 2.0;
    return 0.0;
}
}  // namespace

HeightInterpolant::HeightInterpolant(int rows, int cols, double texel_um, int refine, Interpolant kind)
    : m_rows(rows), m_cols(cols), m_refine(refine) {
    if (rows < 1 || cols < 1 || !(texel_um > 0.0) || refine < 1 || refine > 63 || refine % 2 == 0)
        throw std::invalid_argument("HeightInterpolant: tile " + std::to_string(rows) + " x " + std::to_string(cols) +
                                    ", refine " + std::to_string(refine) +
                                    " is invalid; expected >= 1 texels and an odd refine up to 63");
    const int span = 2 * k_reach + 1, q = refine;
    m_weights.assign(std::size_t(q) * q * span * span, 0.0);
    const auto weight = [&](int sa, int sb, int di, int dj) -> double& {
        return m_weights[((std::size_t(sa) * q + sb) * span + (di + k_reach)) * span + (dj + k_reach)];
    };
    if (kind == Interpolant::Cubic) {
        // Sample (sa, sb) of a texel lies (sa − q/2)/q texels from its centre.
        for (int sa = 0; sa < q; ++sa)
            for (int sb = 0; sb < q; ++sb)
                for (int di = -k_reach; di <= k_reach; ++di)
                    for (int dj = -k_reach; dj <= k_reach; ++dj)
                        weight(sa, sb, di, dj) = keys_kernel(double(sa - q / 2) / q - di) *
                                                 keys_kernel(double(sb - q / 2) / q - dj);
        return;
    }
    // The blend's response to one texel of height 1 µm on a tile wide enough that the stencil
    // does not wrap onto itself.
    constexpr int side = 2 * k_reach + 3, centre = side / 2;
    std::vector<double> impulse(std::size_t(side) * side, 0.0);
    impulse[std::size_t(centre) * side + centre] = 1.0 / texel_um;
    const std::vector<double> response = refined_heights(Heightfield(side, side, impulse, texel_um, 1.0), refine);
    const int fine_cols = side * q;
    // A sample at offset (sa, sb) in texel (centre − di, centre − dj) sees the impulse as its
    // texel's neighbour (di, dj).
    for (int sa = 0; sa < q; ++sa)
        for (int sb = 0; sb < q; ++sb)
            for (int di = -k_reach; di <= k_reach; ++di)
                for (int dj = -k_reach; dj <= k_reach; ++dj)
                    weight(sa, sb, di,
                           dj) = response[std::size_t((centre - di) * q + sa) * fine_cols + (centre - dj) * q + sb];
}

void HeightInterpolant::apply(const std::vector<double>& heights_um, std::vector<double>& fine_um) const {
    const int q = m_refine, span = 2 * k_reach + 1, fine_cols = m_cols * q;
    fine_um.assign(std::size_t(m_rows) * q * fine_cols, 0.0);
    const bool parallel = worth_parallel((long long)fine_um.size() * span * span) && !in_parallel_region();
#pragma omp parallel for schedule(static) if (parallel)
    for (int i = 0; i < m_rows; ++i)
        for (int j = 0; j < m_cols; ++j)
            for (int sa = 0; sa < q; ++sa)
                for (int sb = 0; sb < q; ++sb) {
                    const double* w = m_weights.data() + (std::size_t(sa) * q + sb) * span * span;
                    double sum = 0.0;
                    for (int di = -k_reach; di <= k_reach; ++di) {
                        const int r = ((i + di) % m_rows + m_rows) % m_rows;
                        for (int dj = -k_reach; dj <= k_reach; ++dj) {
                            const int c = ((j + dj) % m_cols + m_cols) % m_cols;
                            sum += w[(di + k_reach) * span + dj + k_reach] * heights_um[std::size_t(r) * m_cols + c];
                        }
                    }
                    fine_um[std::size_t(i * q + sa) * fine_cols + j * q + sb] = sum;
                }
}

void HeightInterpolant::transpose(const std::vector<double>& fine, std::vector<double>& texels) const {
    const int q = m_refine, span = 2 * k_reach + 1, fine_cols = m_cols * q;
    texels.assign(std::size_t(m_rows) * m_cols, 0.0);
    const bool parallel = worth_parallel((long long)fine.size() * span * span) && !in_parallel_region();
    // Gathered per texel (I, J): the samples of texel (I − di, J − dj) that see it as (di, dj).
#pragma omp parallel for schedule(static) if (parallel)
    for (int I = 0; I < m_rows; ++I)
        for (int J = 0; J < m_cols; ++J) {
            double sum = 0.0;
            for (int di = -k_reach; di <= k_reach; ++di) {
                const int i = ((I - di) % m_rows + m_rows) % m_rows;
                for (int dj = -k_reach; dj <= k_reach; ++dj) {
                    const int j = ((J - dj) % m_cols + m_cols) % m_cols;
                    for (int sa = 0; sa < q; ++sa)
                        for (int sb = 0; sb < q; ++sb)
                            sum += m_weights[((std::size_t(sa) * q + sb) * span + (di + k_reach)) * span +
                                             (dj + k_reach)] *
                                   fine[std::size_t(i * q + sa) * fine_cols + j * q + sb];
                }
            }
            texels[std::size_t(I) * m_cols + J] = sum;
        }
}

namespace {

std::vector<double> lambdas_of(const std::vector<const Observation*>& observations, const Communicator& comm) {
    std::vector<double> mine;
    for (const Observation* o : observations)
        if (std::find(mine.begin(), mine.end(), o->lambdas_um[0]) == mine.end()) mine.push_back(o->lambdas_um[0]);
    std::vector<double> all = all_gather(comm, mine);
    std::sort(all.begin(), all.end());
    all.erase(std::unique(all.begin(), all.end()), all.end());
    return all;
}

// Slice value k of o (negative clamped to 0) and its weight (value_weight; a value of weight 0
// is not read: it may be anything).
double weighted_reference(const Observation& o, std::size_t k, double& w) {
    w = value_weight(o, k);
    return w == 0.0 ? 0.0 : std::max(0.0, double(o.reference[k]));
}

// Σ w R over every rank's observations (negative values clamped), exactly.
double reference_total(const std::vector<const Observation*>& observations, const Communicator& comm) {
    std::vector<double> totals(observations.size(), 0.0);
    for (std::size_t i = 0; i < observations.size(); ++i) totals[i] = weighted_reference_total(*observations[i]);
    return exact_total(totals, comm);
}

void check_inputs(const std::vector<const Observation*>& observations, const std::vector<Query>& queries,
                  const char* who) {
    if (observations.size() != queries.size())
        throw std::invalid_argument(std::string(who) + ": " + std::to_string(observations.size()) +
                                    " observations but " + std::to_string(queries.size()) +
                                    " queries; expected one query per observation");
    for (std::size_t i = 0; i < observations.size(); ++i)
        if (!observations[i] || observations[i]->lambdas_um.size() != 1)
            throw std::invalid_argument(std::string(who) + ": observation " + std::to_string(i) +
                                        " is null or not a single-wavelength slice");
}

}  // namespace

struct FieldModelLoss::Impl {
    struct Slice {
        std::unique_ptr<FieldOperator> op;
        // √R on the operator's box, read from the observation's reference at each evaluation
        // (rounded to float as the products are; no copy of the references is kept).
        const Observation* observation = nullptr;
        int a0 = 0, b0 = 0;  // the box's first slice row / column
        std::size_t at(Eigen::Index a, Eigen::Index b) const {
            return std::size_t(a0 + a) * std::size_t(observation->resolution) + std::size_t(b0 + b);
        }
        float sqrt_ref(Eigen::Index a, Eigen::Index b) const {
            return float(std::sqrt(std::max(0.0, double(observation->reference[at(a, b)]))));
        }
        // The pixel weight (read only when the observation has weights).
        float weight(Eigen::Index a, Eigen::Index b) const { return observation->weights[at(a, b)]; }
        double outside = 0.0;  // Σ w R beyond the box
        int lambda = 0;        // index into lambdas
        double k = 0.0;        // 4π/λ (1/µm)
        double scale = 1.0;    // of the field (the window's integral)
    };
    std::vector<Slice> slices;
    std::vector<double> lambdas;
    HeightInterpolant interpolant;
    int fine_cols = 0;
    std::size_t fine = 0;
    double inv_total = 0.0;
    bool calibrate_exposure = false;
    const Communicator* comm = nullptr;
    mutable ExactParallelSum exact_sum;
    mutable std::vector<double> fine_um, fine_gradient;
    // The object e^{−i k H̃} of one wavelength at a time (its slices' terms are summed, then the
    // next wavelength's: the exact sums do not depend on the order).
    mutable std::vector<std::complex<double>> object;
    std::vector<std::vector<std::size_t>> by_lambda;  // this rank's slices per wavelength

    Impl(int rows, int cols, double texel_um, int refine, Interpolant kind)
        : interpolant(rows, cols, texel_um, refine, kind),
          fine_cols(cols * refine),
          fine(std::size_t(rows) * refine * std::size_t(cols) * refine),
          exact_sum(fine) {}
};

FieldModelLoss::FieldModelLoss(const std::vector<const Observation*>& observations, const std::vector<Query>& queries,
                               int rows, int cols, double texel_um, int refine, bool calibrate_exposure,
                               const Communicator& comm, Interpolant interpolant, bool gabor_window)
    : m_impl(std::make_unique<Impl>(rows, cols, texel_um, refine, interpolant)) {
    check_inputs(observations, queries, "FieldModelLoss");
    Impl& s = *m_impl;
    s.comm = &comm;
    s.calibrate_exposure = calibrate_exposure;
    s.lambdas = lambdas_of(observations, comm);
    const double total = reference_total(observations, comm);
    if (!(total > 0.0)) throw std::invalid_argument("FieldModelLoss: every reference slice is zero");
    s.inv_total = 1.0 / total;
    s.slices.resize(observations.size());
    RegionGuard guard;
#pragma omp parallel for schedule(dynamic) if (observations.size() > 1 && !in_parallel_region())
    for (std::size_t i = 0; i < observations.size(); ++i)
        guard.run([&] {
            const Observation& o = *observations[i];
            const double lambda = o.lambdas_um[0];
            Impl::Slice& slice = s.slices[i];
            Query query = queries[i];
            if (gabor_window) {
                const double d = texel_um / refine, sigma = query.sigma_p_um;
                query.sigma_p_um = std::sqrt(sigma * sigma + 0.25 * (texel_um * texel_um - d * d));
                slice.scale = sigma / query.sigma_p_um;
            }
            slice.op = std::make_unique<FieldOperator>(rows, cols, texel_um, query, lambda, o.resolution, refine);
            slice.lambda = int(std::lower_bound(s.lambdas.begin(), s.lambdas.end(), lambda) - s.lambdas.begin());
            slice.k = 4.0 * k_pi / lambda;
            int a0 = 0, b0 = 0;
            const Eigen::MatrixXd& amp = field_amplitude_box(*slice.op, a0, b0);
            slice.observation = &o;
            slice.a0 = a0;
            slice.b0 = b0;
            const int n = o.resolution;
            if (a0 < 0 || b0 < 0 || a0 + amp.rows() > n || b0 + amp.cols() > n)
                throw std::logic_error("FieldModelLoss: observation " + std::to_string(i) +
                                       "'s pixel box lies outside its slice");
            for (int p = 0; p < n; ++p)
                for (int c = 0; c < n; ++c) {
                    double w = 1.0;
                    const double r = weighted_reference(o, std::size_t(p) * n + c, w);
                    const int a = p - a0, b = c - b0;
                    if (!(a >= 0 && a < amp.rows() && b >= 0 && b < amp.cols())) slice.outside += w * r;
                }
        });
    guard.rethrow();
    s.by_lambda.resize(s.lambdas.size());
    for (std::size_t i = 0; i < s.slices.size(); ++i) s.by_lambda[std::size_t(s.slices[i].lambda)].push_back(i);
}

FieldModelLoss::~FieldModelLoss() = default;

double FieldModelLoss::operator()(const std::vector<double>& heights_um, std::vector<double>* gradient) const {
    const Impl& s = *m_impl;
    s.interpolant.apply(heights_um, s.fine_um);
    // One wavelength's object at a time (not all of them on the fine grid at once).
    std::vector<std::complex<double>>& object = s.object;
    object.resize(s.fine);
    bool accumulate = false;
    for (std::size_t l = 0; l < s.lambdas.size(); ++l) {
        const std::vector<std::size_t>& group = s.by_lambda[l];
        if (group.empty()) continue;
        const double k = 4.0 * k_pi / s.lambdas[l];
        const bool parallel = worth_parallel((long long)s.fine) && !in_parallel_region();
#pragma omp parallel for schedule(static) if (parallel)
        for (std::size_t t = 0; t < s.fine; ++t) object[t] = std::polar(1.0, -k * s.fine_um[t]);
        // Slice i's term (as retrieve_field's, recover_field.cpp); its object gradient
        // G = ∂L/∂Re O + i ∂L/∂Im O mapped to the fine heights, ∂L/∂H̃ = k Im(conj(G) O).
        s.exact_sum.run_local(
            group.size(),
            [&](std::size_t gi, ExactScratch& scratch) {
                thread_local Eigen::MatrixXcf psi, g;
                thread_local std::vector<std::complex<double>> object_gradient;
                if (object_gradient.size() != s.fine) object_gradient.assign(s.fine, 0.0);
                const Impl::Slice& slice = s.slices[group[gi]];
                int a0 = 0, b0 = 0;
                const Eigen::MatrixXd& amp_box = field_amplitude_box(*slice.op, a0, b0);
                const Eigen::MatrixXd amp = slice.scale * amp_box;
                field_forward_unphased(*slice.op, object.data(), psi);
                const auto sqrt_ref = [&](Eigen::Index a, Eigen::Index b) { return slice.sqrt_ref(a, b); };
                const double v =
                    slice.observation->weights.empty()
                        ? amplitude_box_loss(psi, amp, sqrt_ref, UnitWeight{}, slice.outside, s.calibrate_exposure,
                                             s.inv_total, g)
                        : amplitude_box_loss(
                              psi, amp, sqrt_ref, [&](Eigen::Index a, Eigen::Index b) { return slice.weight(a, b); },
                              slice.outside, s.calibrate_exposure, s.inv_total, g);
                field_adjoint_unphased_add(*slice.op, g, object_gradient.data());
                const std::vector<int>& rows = field_rows(*slice.op);
                const std::vector<int>& cols = field_cols(*slice.op);
                double* out = scratch.data();
                for (int r : rows)
                    for (int c : cols) {
                        const std::size_t t = std::size_t(r) * s.fine_cols + c;
                        out[t] += slice.k * std::imag(std::conj(object_gradient[t]) * object[t]);
                        object_gradient[t] = 0.0;
                    }
                scratch.take_box(rows, cols, std::size_t(s.fine_cols));
                return v * s.inv_total;
            },
            accumulate);
        accumulate = true;
    }
    s.fine_gradient.resize(s.fine);
    const double value = s.exact_sum.finish(*s.comm, s.fine_gradient.data());
    if (gradient) s.interpolant.transpose(s.fine_gradient, *gradient);
    return value;
}

namespace {

// Observation o's slice in the Gabor model at `heightfield` (its query `query`), scaled by its
// fitted exposure where calibrate_exposure, on the reference's values (0 past the slice's).
std::vector<double> gabor_model_slice(const Observation& o, const Query& query, const Heightfield& heightfield,
                                      bool calibrate_exposure) {
    SlicePlan<float> plan(heightfield, query, o.lambdas_um, o.resolution, 1);
    const std::vector<float>& f = plan.forward();
    const std::size_t n = std::min(f.size(), o.reference.size());
    const double e = calibrate_exposure ? observation_exposure(f, o) : 1.0;  // over the weighted pixels
    std::vector<double> model(o.reference.size(), 0.0);
    for (std::size_t k = 0; k < n; ++k) model[k] = e * double(f[k]);
    return model;
}

}  // namespace

double gabor_amplitude_loss(const std::vector<const Observation*>& observations, const std::vector<Query>& queries,
                            const Heightfield& heightfield, bool calibrate_exposure, const Communicator& comm) {
    check_inputs(observations, queries, "gabor_amplitude_loss");
    const double total = reference_total(observations, comm);
    if (!(total > 0.0)) throw std::invalid_argument("gabor_amplitude_loss: every reference slice is zero");
    std::vector<double> no_gradient;
    ExactParallelSum sum(0);
    return sum.run(observations.size(), comm, no_gradient, [&](std::size_t i, ExactScratch&) {
        const Observation& o = *observations[i];
        const std::vector<double> model = gabor_model_slice(o, queries[i], heightfield, calibrate_exposure);
        double v = 0.0;
        for (std::size_t k = 0; k < o.reference.size(); ++k) {
            double w = 1.0;
            const double r = weighted_reference(o, k, w);
            if (w == 0.0) continue;
            const double d = std::sqrt(std::max(0.0, model[k])) - std::sqrt(r);
            v += w * (d * d);
        }
        return v;
    }) / total;
}

SliceDeviance gabor_photon_deviance(const std::vector<const Observation*>& observations,
                                    const std::vector<Query>& queries, const Heightfield& heightfield,
                                    bool calibrate_exposure, double photons, const Communicator& comm) {
    check_inputs(observations, queries, "gabor_photon_deviance");
    ExactParallelSum sum(2);
    std::vector<double> moments;
    SliceDeviance d;
    d.deviance = sum.run(observations.size(), comm, moments, [&](std::size_t i, ExactScratch& scratch) {
        const Observation& o = *observations[i];
        const SliceDeviance one =
            slice_photon_deviance(o, gabor_model_slice(o, queries[i], heightfield, calibrate_exposure), photons);
        scratch.data()[0] = one.expected;
        scratch.data()[1] = one.variance;
        scratch.take_all();
        return one.deviance;
    });
    d.expected = moments[0];
    d.variance = moments[1];
    return d;
}

std::vector<double> heights_um_of(const Heightfield& heights) {
    std::vector<double> h(heights.values().size());
    for (int i = 0; i < heights.rows(); ++i)
        for (int j = 0; j < heights.cols(); ++j) h[std::size_t(i) * heights.cols() + j] = heights.height_um(i, j);
    return h;
}

Heightfield refine_in_field_model(const FieldModelLoss& model, const Heightfield& start, int iterations, int history,
                                  int stall_window, double stall_tolerance,
                                  const std::function<bool(int, double, const Heightfield&)>& on_iteration,
                                  double* loss, const FieldModelEvaluation* at_start) {
    const double to_texel = 1.0 / (start.vscale() * start.texel_um());
    std::vector<double> h = heights_um_of(start);
    if (at_start && at_start->gradient.size() != h.size())
        throw std::invalid_argument("refine_in_field_model: at_start's gradient has " +
                                    std::to_string(at_start->gradient.size()) + " values; expected " +
                                    std::to_string(h.size()));
    const std::vector<double> h0 = h;
    bool first = at_start != nullptr;
    const auto heights = [&](const std::vector<double>& x) {
        std::vector<double> v(x.size());
        for (std::size_t k = 0; k < x.size(); ++k) v[k] = x[k] * to_texel;
        return start.with_values(std::move(v));
    };
    LbfgsOptions lo;
    lo.history = std::max(1, history);
    lo.max_iterations = std::max(0, iterations);
    lo.gradient_tolerance = 0.0;
    detail::StallRule stall(stall_window, stall_tolerance);
    const LbfgsResult r = lbfgs_minimize(
        [&](const std::vector<double>& x, std::vector<double>& g) {
            // L-BFGS's first evaluation is at the start: the caller's evaluation there is reused.
            if (first && x == h0) {
                first = false;
                g = at_start->gradient;
                return at_start->loss;
            }
            first = false;
            return model(x, &g);
        },
        h, lo,
        [&](int it, double value) {
            if (on_iteration && !on_iteration(it, value, heights(h))) return false;
            return !stall.stalled_at(value);
        });
    if (loss) *loss = r.value;
    return heights(h);
}

bool skip_field_refinement(double gabor_loss, double field_start_loss, double skip_ratio) {
    if (!(skip_ratio >= 0.0 && skip_ratio <= 1.0))
        throw std::invalid_argument("model_check_skip_ratio " + std::to_string(skip_ratio) +
                                    " is out of range; expected 0 to 1");
    return skip_ratio > 0.0 && gabor_loss < skip_ratio * field_start_loss;
}

Heightfield check_model(const std::vector<const Observation*>& separable, const std::vector<std::size_t>& index,
                        const std::vector<std::array<double, 2>>& offsets_um, double sigma_scale,
                        const Heightfield& unwrapped, const Heightfield& refined, int refine,
                        const ModelCheckSettings& settings, const StageReport& report, const Communicator& comm,
                        double field_floor_loss) {
    std::vector<Query> queries;
    queries.reserve(separable.size());
    for (std::size_t i = 0; i < separable.size(); ++i) {
        Query q = separable[i]->query;
        if (!offsets_um.empty()) {
            q.x_um += offsets_um[index[i]][0];
            q.y_um += offsets_um[index[i]][1];
        }
        q.sigma_p_um *= sigma_scale;
        queries.push_back(q);
    }
    const bool exposure = settings.calibrate_exposure;
    const double gabor = gabor_amplitude_loss(separable, queries, refined, exposure, comm);
    if (!report({StageKind::ModelMisfit, "gabor"}, 0, gabor, &refined)) return refined;
    // The field model's loss at any heights is not expected below the field stage's floor (its
    // retrievals minimised it over free objects): skipped without building the model.
    if (field_floor_loss > 0.0 && skip_field_refinement(gabor, field_floor_loss, settings.skip_ratio)) {
        if (!report({StageKind::ModelMisfit, "field-floor"}, 0, field_floor_loss, &unwrapped)) return refined;
        report({StageKind::ModelSelect, "gabor"}, 0, gabor, &refined);
        return refined;
    }
    // With photon counts (the refinement's Poisson loss): the Gabor heights whose deviance is on
    // the noise floor (the convergence check's rule) explain the slices as well as their noise
    // allows, so no other model can explain them measurably better; they are kept. A field
    // refinement would only fit the noise another way: refined in the amplitude loss that
    // decides below, it wins that comparison against the Gabor fit made in the deviance while
    // its heights are further off (0.77 % against 0.27 % on a real scan at 64², docs/surfaces.md).
    const double photons = settings.loss.kind == LossKind::Poisson ? settings.loss.photons : 0.0;
    if (photons > 0.0) {
        const SliceDeviance d = gabor_photon_deviance(separable, queries, refined, exposure, photons, comm);
        if (d.expected > 0.0) {
            if (!report({StageKind::ModelMisfit, "gabor-noise"}, 0, d.deviance / d.expected, &refined)) return refined;
            if (misfit_on_photon_floor(d.deviance, d.expected, std::sqrt(d.variance))) {
                report({StageKind::ModelSelect, "gabor"}, 0, gabor, &refined);
                return refined;
            }
        }
    }
    const FieldModelLoss model(separable, queries, refined.rows(), refined.cols(), refined.texel_um(), refine, exposure,
                               comm);
    // The field model at its start (the unwrapped heights; L-BFGS's first evaluation, reused):
    // when the Gabor model already explains the slices far better than that, the refinement,
    // which lowers the field model's loss by ~25 % on such data (by ~5 × on scalar-diffraction
    // data), cannot overtake it and is skipped (recover.h, model_check_skip_ratio).
    FieldModelEvaluation at_start;
    at_start.loss = model(heights_um_of(unwrapped), &at_start.gradient);
    if (!report({StageKind::ModelMisfit, "field-start"}, 0, at_start.loss, &unwrapped)) return refined;
    if (skip_field_refinement(gabor, at_start.loss, settings.skip_ratio)) {
        report({StageKind::ModelSelect, "gabor"}, 0, gabor, &refined);
        return refined;
    }
    bool go_on = true;
    double field = 0.0;
    const Heightfield in_field = refine_in_field_model(
        model, unwrapped, settings.iterations, settings.history, settings.stall_window, settings.stall_tolerance,
        [&](int it, double value, const Heightfield& h) {
            return go_on = report(StageKind::ModelRefine, it, value, &h);
        },
        &field, &at_start);
    if (!go_on || !report({StageKind::ModelMisfit, "field"}, 0, field, &in_field)) return refined;
    const bool keep_field = field < gabor;
    const Heightfield& chosen = keep_field ? in_field : refined;
    report({StageKind::ModelSelect, keep_field ? "field" : "gabor"}, 0, std::min(field, gabor), &chosen);
    return chosen;
}

}  // namespace wavebrdf::detail
