// The recovery's model check (src/recovery/recover_field_model.h; docs/recovery.md, "Model
// robustness"): the interpolant against refined_heights, the field model's loss against an
// independent evaluation with FieldOperator and its gradient against finite differences, and
// the pipeline on scalar-diffraction slices (not the Gabor model's) and on the Gabor model's.
#include "recovery/recover_field_model.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <random>
#include <string>
#include <vector>

#include "recover_util.h"
#include "test_util.h"
#include "wavebrdf/convergence.h"
#include "wavebrdf/generate.h"
#include "wavebrdf/noise.h"
#include "wavebrdf/recover.h"
#include "wavebrdf/recovery_run.h"
#include "wavebrdf/scalar_diffraction.h"

using namespace wavebrdf;

namespace {

// A few single-wavelength OHS slices of `hf` (rendered in the Gabor model: any data will do).
std::vector<Observation> few_slices(const Heightfield& hf, const std::vector<double>& lambdas, int resolution) {
    std::vector<Observation> out;
    for (double lambda : lambdas)
        for (int a = 0; a < 2; ++a)
            for (int b = 0; b < 2; ++b) {
                Observation o;
                o.query = test::make_query(Model::OHS, 5.0 + 9.0 * a, 6.0 + 8.5 * b, 3.0);
                o.lambdas_um.assign(1, lambda);
                o.resolution = resolution;
                o.reference = to_reference(render_observation(hf, o));
                out.push_back(std::move(o));
            }
    return out;
}

std::vector<const Observation*> pointers(const std::vector<Observation>& observations) {
    std::vector<const Observation*> p;
    for (const Observation& o : observations) p.push_back(&o);
    return p;
}

std::vector<Query> queries_of(const std::vector<Observation>& observations) {
    std::vector<Query> q;
    for (const Observation& o : observations) q.push_back(o.query);
    return q;
}

}  // namespace

// The stencil form of the tangent-plane blend equals refined_heights (recover.h) everywhere,
// also on a tile smaller than the stencil (9 texels) where it wraps; its transpose is the
// adjoint (⟨A x, y⟩ = ⟨x, Aᵀ y⟩).
TEST(HeightInterpolant, EqualsRefinedHeightsAndItsTransposeIsTheAdjoint) {
    for (const auto& [rows, cols, refine] : std::vector<std::array<int, 3>>{{12, 10, 3}, {7, 13, 5}, {16, 16, 1}}) {
        const Heightfield hf = test::random_heightfield(rows, cols, 0.6, 5701 + rows, 2.0);
        const detail::HeightInterpolant interpolant(rows, cols, 2.0, refine, detail::Interpolant::Blend);
        std::vector<double> fine;
        interpolant.apply(heights_um(hf), fine);
        const std::vector<double> expected = refined_heights(hf, refine);
        ASSERT_EQ(fine.size(), expected.size());
        double worst = 0.0;
        for (std::size_t k = 0; k < fine.size(); ++k) worst = std::max(worst, std::abs(fine[k] - expected[k]));
        EXPECT_LT(worst, 1e-12) << rows << " x " << cols << ", refine " << refine;

        std::mt19937_64 rng(5702);
        std::normal_distribution<double> normal;
        std::vector<double> x(std::size_t(rows) * cols), y(fine.size()), ax, aty;
        for (double& v : x) v = normal(rng);
        for (double& v : y) v = normal(rng);
        interpolant.apply(x, ax);
        interpolant.transpose(y, aty);
        double left = 0.0, right = 0.0;
        for (std::size_t k = 0; k < y.size(); ++k) left += ax[k] * y[k];
        for (std::size_t k = 0; k < x.size(); ++k) right += x[k] * aty[k];
        EXPECT_NEAR(left, right, 1e-10 * std::abs(left));
    }
}

// The loss runs one wavelength's slices at a time (one object on the fine grid): given in any
// order (the wavelengths interleaved, reversed), the same value and gradient to the bit, with
// and without the exposure calibration.
TEST(FieldModelLoss, OneWavelengthAtATimeInAnyOrderGivesTheSameBits) {
    const int n = 12, refine = 3, resolution = 24;
    const Heightfield truth = test::random_heightfield(n, n, 0.15, 5707, 2.0);
    const std::vector<Observation> observations = few_slices(truth, {0.5, 0.6, 0.7}, resolution);
    std::vector<Observation> shuffled;
    for (std::size_t k = 0; k < 4; ++k)
        for (std::size_t l = 3; l-- > 0;) shuffled.push_back(observations[l * 4 + (k * 3 + l) % 4]);
    ASSERT_EQ(shuffled.size(), observations.size());
    const std::vector<double> h = heights_um(test::random_heightfield(n, n, 0.15, 5708, 2.0));
    for (bool exposure : {false, true}) {
        const detail::FieldModelLoss a(pointers(observations), queries_of(observations), n, n, 2.0, refine, exposure,
                                       serial_communicator());
        const detail::FieldModelLoss b(pointers(shuffled), queries_of(shuffled), n, n, 2.0, refine, exposure,
                                       serial_communicator());
        std::vector<double> ga, gb;
        const double va = a(h, &ga), vb = b(h, &gb);
        EXPECT_GT(va, 0.0);
        EXPECT_EQ(va, vb) << "exposure " << exposure;
        EXPECT_EQ(ga, gb) << "exposure " << exposure;
        EXPECT_EQ(a(h, nullptr), va);  // a second evaluation starts from zero sums
    }
}

// Pixel weights (Observation::weights) in the model check's losses: a pixel of weight 0 enters
// neither the field model's loss nor the Gabor amplitude loss (its value, here 50 × the slice's
// peak or NaN, changes neither value nor gradient), and the weights count (the weighted loss
// differs from the unweighted one). Each slice's brightest pixel is among those masked: on the
// planner's 48² slices 3 % of the pixels hid one slice's specular peak, and the model check,
// reading values filled from its dim neighbours unweighted, swapped the refined heights (4e-6
// off) for the field model's (3 % off; tests/python/test_recover_weights.py).
TEST(FieldModelLoss, PixelsOfWeightZeroEnterNeitherModelCheckLoss) {
    const int n = 12, refine = 3, resolution = 24;
    const Heightfield truth = test::random_heightfield(n, n, 0.15, 5709, 2.0);
    const std::vector<Observation> clean = few_slices(truth, {0.5, 0.6}, resolution);
    std::vector<Observation> masked = clean, garbage;
    std::mt19937_64 rng(5710);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    for (Observation& o : masked) {
        o.weights.assign(o.reference.size(), 1.0f);
        const std::size_t peak =
            std::size_t(std::max_element(o.reference.begin(), o.reference.end()) - o.reference.begin());
        o.weights[peak] = 0.0f;
        for (float& w : o.weights)
            if (u(rng) < 0.05) w = 0.0f;
        for (float& w : o.weights)
            if (w != 0.0f) w = float(0.5 + u(rng));
    }
    garbage = masked;
    for (Observation& o : garbage) {
        const float peak = *std::max_element(o.reference.begin(), o.reference.end());
        bool first = true;
        for (std::size_t k = 0; k < o.reference.size(); ++k)
            if (o.weights[k] == 0.0f) {
                o.reference[k] = first ? std::numeric_limits<float>::quiet_NaN() : 50.0f * peak;
                first = false;
            }
    }
    const Heightfield start = test::random_heightfield(n, n, 0.15, 5711, 2.0);
    const std::vector<double> h = heights_um(start);
    for (bool exposure : {false, true}) {
        SCOPED_TRACE(exposure ? "exposure calibrated" : "exposure 1");
        const auto field_loss = [&](const std::vector<Observation>& obs, std::vector<double>& g) {
            const detail::FieldModelLoss loss(pointers(obs), queries_of(obs), n, n, 2.0, refine, exposure,
                                              serial_communicator());
            return loss(h, &g);
        };
        std::vector<double> g_clean, g_masked, g_garbage;
        const double v_clean = field_loss(clean, g_clean), v_masked = field_loss(masked, g_masked),
                     v_garbage = field_loss(garbage, g_garbage);
        EXPECT_TRUE(std::isfinite(v_garbage));
        EXPECT_EQ(v_masked, v_garbage);
        EXPECT_EQ(g_masked, g_garbage);
        EXPECT_GT(std::abs(v_masked - v_clean), 1e-3 * v_clean);  // the weights count
        const auto gabor = [&](const std::vector<Observation>& obs, const Heightfield& at) {
            return detail::gabor_amplitude_loss(pointers(obs), queries_of(obs), at, exposure, serial_communicator());
        };
        EXPECT_EQ(gabor(masked, start), gabor(garbage, start));
        EXPECT_GT(std::abs(gabor(masked, start) - gabor(clean, start)), 1e-3 * gabor(clean, start));
        // The slices are the Gabor model's: at the truth the weighted loss is ~0 whatever the
        // masked pixels hold.
        EXPECT_LT(gabor(garbage, truth), 1e-9);
    }
}

// The cubic interpolant passes through every texel centre (sample q/2 of each texel) and its
// transpose is the adjoint.
TEST(HeightInterpolant, CubicPassesThroughTheTexelCentres) {
    const int rows = 9, cols = 11, q = 5;
    const Heightfield hf = test::random_heightfield(rows, cols, 0.6, 5706, 2.0);
    const std::vector<double> h = heights_um(hf);
    const detail::HeightInterpolant interpolant(rows, cols, 2.0, q, detail::Interpolant::Cubic);
    std::vector<double> fine;
    interpolant.apply(h, fine);
    for (int i = 0; i < rows; ++i)
        for (int j = 0; j < cols; ++j)
            EXPECT_NEAR(fine[std::size_t(i * q + q / 2) * (cols * q) + j * q + q / 2], h[std::size_t(i) * cols + j],
                        1e-12);
    std::vector<double> y(fine.size()), aty;
    for (std::size_t k = 0; k < y.size(); ++k) y[k] = std::sin(0.1 * double(k));
    interpolant.transpose(y, aty);
    double left = 0.0, right = 0.0;
    for (std::size_t k = 0; k < y.size(); ++k) left += fine[k] * y[k];
    for (std::size_t k = 0; k < h.size(); ++k) right += h[k] * aty[k];
    EXPECT_NEAR(left, right, 1e-10 * std::abs(left));
}

// The loss equals Σ(√c1 |F e^{−i(4π/λ)H̃}| − √R)² / Σ R (H̃ the cubic) evaluated independently with
// FieldOperator::forward (double precision, phases included), and its gradient matches central
// differences, with and without the exposure calibration.
TEST(FieldModelLoss, MatchesAnIndependentEvaluationAndFiniteDifferences) {
    const int n = 12, refine = 3, resolution = 24;
    const Heightfield truth = test::random_heightfield(n, n, 0.15, 5703, 2.0);
    const std::vector<Observation> observations = few_slices(truth, {0.5, 0.6}, resolution);
    const Heightfield start = test::random_heightfield(n, n, 0.15, 5704, 2.0);
    const std::vector<double> h = heights_um(start);
    std::vector<double> fine;
    detail::HeightInterpolant(n, n, 2.0, refine).apply(heights_um(start), fine);
    double num = 0.0, den = 0.0;
    for (const Observation& o : observations) {
        const FieldOperator op(n, n, 2.0, o.query, o.lambdas_um[0], resolution, refine);
        std::vector<std::complex<double>> object(fine.size());
        for (std::size_t t = 0; t < fine.size(); ++t)
            object[t] = std::polar(1.0, -4.0 * M_PI / o.lambdas_um[0] * fine[t]);
        const std::vector<std::complex<double>> field = op.forward(object);
        for (std::size_t p = 0; p < field.size(); ++p) {
            const double d = op.amplitude_factor()[p] * std::abs(field[p]) -
                             std::sqrt(std::max(0.0, double(o.reference[p])));
            num += d * d;
            den += std::max(0.0, double(o.reference[p]));
        }
    }
    for (bool exposure : {false, true}) {
        const detail::FieldModelLoss loss(pointers(observations), queries_of(observations), n, n, 2.0, refine, exposure,
                                          serial_communicator(), detail::Interpolant::Cubic, false);
        std::vector<double> g;
        const double value = loss(h, &g);
        if (!exposure) {
            EXPECT_NEAR(value, num / den, 1e-5 * num / den);  // the products in single precision
        }
        ASSERT_EQ(g.size(), h.size());
        for (std::size_t k : {std::size_t(0), std::size_t(29), std::size_t(77), std::size_t(140)}) {
            const double step = 1e-4;
            std::vector<double> plus = h, minus = h;
            plus[k] += step;
            minus[k] -= step;
            const double fd = (loss(plus, nullptr) - loss(minus, nullptr)) / (2.0 * step);
            EXPECT_NEAR(g[k], fd, 1e-2 * std::abs(fd) + 1e-6)  // single-precision products
                << "texel " << k << ", exposure " << exposure;
        }
    }
}

namespace {

struct ScalarCase {
    Heightfield truth;
    std::vector<Observation> observations;
};

// A smooth ±0.5 µm surface (correlation 8 µm, 12², texel 2 µm) seen at 6 × 6 jittered
// positions (σ_p = 3 µm, 78 % overlap) and two wavelengths, 32² slices simulated by
// `simulator` (recover_test's small case).
ScalarCase small_scalar_case(Simulator simulator, std::uint64_t seed) {
    const Heightfield surface = test::peak_scaled_surface(12, 8.0, 0.5, seed);
    ScalarCase c{surface, test::small_case_footprints(seed, 32)};
    for (Observation& o : c.observations)
        o.reference = to_reference(simulator == Simulator::Scalar
                                       ? scalar_slice(c.truth, o.query, o.lambdas_um[0], o.resolution)
                                       : render_observation(c.truth, o));
    return c;
}

std::map<std::string, double> run_stages(const ScalarCase& c, RecoverSettings s, std::string* selected) {
    std::map<std::string, double> rmse;
    const Heightfield estimate = recover_heights(
        c.observations, 12, 12, 2.0, 1.0, s,
        [&](const StageMetrics& m) {
            if (m.height_rel_rmse >= 0.0) rmse[m.stage] = m.height_rel_rmse;
            if (selected && m.stage.rfind("select:", 0) == 0) *selected = m.stage;
            if (m.stage.rfind("misfit:", 0) == 0) rmse[m.stage + ":loss"] = m.loss;
            return true;
        },
        &c.truth);
    rmse["final"] = height_rel_rmse(estimate, c.truth);
    return rmse;
}

RecoverSettings small_settings() {
    RecoverSettings s;
    s.blurred.blur_widths = {12.0, 4.0};
    s.blurred.iterations = 15;
    s.field.iterations = 40;
    s.refine_iterations = 15;
    s.model_check_iterations = 15;
    return s;
}

}  // namespace

// On scalar-diffraction slices the Gabor refinement fits a model the data do not follow; the
// model check keeps the field model's heights, no worse than the unwrapped ones (measured
// bound: experiments/2026-11-23-scalar-diffraction-model-check.md).
TEST(ModelCheck, OnScalarSlicesTheResultIsNoWorseThanTheUnwrappedHeights) {
    const ScalarCase c = small_scalar_case(Simulator::Scalar, 5705);
    std::string selected;
    const std::map<std::string, double> r = run_stages(c, small_settings(), &selected);
    for (const auto& [k, v] : r) RecordProperty(k, std::to_string(v));
    ASSERT_TRUE(r.count("unwrap") && r.count("refine") && r.count("misfit:field:loss"));
    EXPECT_EQ(selected, "select:field");
    EXPECT_LT(r.at("misfit:field:loss"), r.at("misfit:gabor:loss"));
    EXPECT_LE(r.at("final"), 1.05 * r.at("unwrap"));
    EXPECT_LT(r.at("final"), r.at("refine"));
}

// On the Gabor model's own slices the Gabor refinement explains them (loss far below the field
// model's floor) and is kept: the final heights are stage 3's, as without the check.
TEST(ModelCheck, OnGaborSlicesTheRefinementIsKept) {
    const ScalarCase c = small_scalar_case(Simulator::Gabor, 5705);
    std::string selected;
    const std::map<std::string, double> r = run_stages(c, small_settings(), &selected);
    for (const auto& [k, v] : r) RecordProperty(k, std::to_string(v));
    EXPECT_EQ(selected, "select:gabor");
    EXPECT_EQ(r.at("final"), r.at("refine"));  // stage 3's heights, as without the check
}

// The model check's shortcut (RecoverSettings::model_check_skip_ratio): the field refinement is
// skipped only when misfit:gabor is below the ratio times the field model's start loss; 0
// never skips; outside [0, 1] is refused (also by recover_heights, before any stage runs).
TEST(ModelCheck, SkipRuleAndItsRange) {
    EXPECT_TRUE(detail::skip_field_refinement(1e-4, 1e-2, 0.1));
    EXPECT_FALSE(detail::skip_field_refinement(2e-3, 1e-2, 0.1));
    EXPECT_FALSE(detail::skip_field_refinement(1e-9, 1e-2, 0.0));
    EXPECT_THROW(detail::skip_field_refinement(1e-4, 1e-2, -0.1), std::invalid_argument);
    EXPECT_THROW(detail::skip_field_refinement(1e-4, 1e-2, 1.5), std::invalid_argument);
    const ScalarCase c = small_scalar_case(Simulator::Gabor, 6601);
    RecoverSettings s = small_settings();
    s.model_check_skip_ratio = 2.0;
    EXPECT_THROW(recover_heights(c.observations, 12, 12, 2.0, 1.0, s, {}), std::invalid_argument);
}

// The refinement's first evaluation taken from the caller (at_start) changes nothing: the same
// heights and loss, bit for bit, as L-BFGS evaluating the start itself.
TEST(ModelCheck, ReusedStartEvaluationGivesTheSameRefinement) {
    const int n = 12, refine = 3, resolution = 24;
    const Heightfield truth = test::random_heightfield(n, n, 0.15, 6602, 2.0);
    const std::vector<Observation> observations = few_slices(truth, {0.5, 0.6}, resolution);
    const Heightfield start = test::random_heightfield(n, n, 0.15, 6603, 2.0);
    const detail::FieldModelLoss model(pointers(observations), queries_of(observations), n, n, 2.0, refine, false,
                                       serial_communicator());
    double plain_loss = 0.0, reused_loss = 0.0;
    const Heightfield plain = detail::refine_in_field_model(model, start, 4, 5, 0, 0.0, {}, &plain_loss);
    detail::FieldModelEvaluation at_start;
    at_start.loss = model(detail::heights_um_of(start), &at_start.gradient);
    const Heightfield reused = detail::refine_in_field_model(model, start, 4, 5, 0, 0.0, {}, &reused_loss, &at_start);
    EXPECT_EQ(plain.values(), reused.values());
    EXPECT_EQ(plain_loss, reused_loss);
    EXPECT_NE(plain.values(), start.values());  // it moved
    detail::FieldModelEvaluation wrong;
    wrong.gradient.assign(3, 0.0);
    EXPECT_THROW(detail::refine_in_field_model(model, start, 4, 5, 0, 0.0, {}, nullptr, &wrong), std::invalid_argument);
}

// On the Gabor model's own slices misfit:gabor is far below the field model's start loss: the
// field refinement is skipped ("refine:field" never reported) and the heights are the same
// bits as with the refinement run and lost (skip ratio 0).
TEST(ModelCheck, OnGaborSlicesTheFieldRefinementIsSkippedWithTheSameResult) {
    const ScalarCase c = small_scalar_case(Simulator::Gabor, 6604);
    const auto run = [&](double ratio, std::map<std::string, int>* stages) {
        RecoverSettings s = small_settings();
        s.model_check_skip_ratio = ratio;
        return recover_heights(c.observations, 12, 12, 2.0, 1.0, s, [&](const StageMetrics& m) {
            ++(*stages)[m.stage];
            return true;
        });
    };
    std::map<std::string, int> skipped, full;
    const Heightfield a = run(0.1, &skipped);
    const Heightfield b = run(0.0, &full);
    EXPECT_EQ(a.values(), b.values());
    EXPECT_EQ(skipped.count("refine:field"), 0u);
    EXPECT_EQ(skipped.count("misfit:field"), 0u);
    // The field stage's floor decides already (no field model built), or its start does.
    EXPECT_EQ(skipped.count("misfit:field-start") + skipped.count("misfit:field-floor"), 1u);
    EXPECT_EQ(skipped.count("select:gabor"), 1u);
    EXPECT_GT(full.count("refine:field"), 0u);
    EXPECT_EQ(full.count("select:gabor"), 1u);
}

// The field-floor shortcut (check_model's field_floor_loss): when misfit:gabor is below the
// skip ratio times the field stage's floor, the field model is not built ("misfit:field-floor"
// instead of "misfit:field-start") and stage 3's heights are kept; a floor too low for the rule,
// or none (0), evaluates the field model's start as before. The heights are the same bits.
TEST(ModelCheck, FieldFloorShortcutSkipsBuildingTheFieldModel) {
    const ScalarCase c = small_scalar_case(Simulator::Gabor, 6605);
    std::vector<double> near = c.truth.values();
    for (std::size_t k = 0; k < near.size(); ++k) near[k] += 0.002 * std::sin(0.7 * double(k));
    const Heightfield refined = c.truth.with_values(near);
    std::vector<std::size_t> index(c.observations.size());
    for (std::size_t k = 0; k < index.size(); ++k) index[k] = k;
    detail::ModelCheckSettings s;  // the library's defaults
    s.iterations = 2;
    const auto run = [&](double floor, std::map<std::string, double>* stages) {
        return detail::check_model(
            pointers(c.observations), index, {}, 1.0, c.truth, refined, 3, s,
            [&](const detail::StageId& stage, int, double loss, const Heightfield*) {
                EXPECT_EQ(stage.kind, stage_kind(stage.name)) << stage.name;
                (*stages)[stage.name] = loss;
                return true;
            },
            serial_communicator(), floor);
    };
    std::map<std::string, double> none, low, high;
    const Heightfield a = run(0.0, &none);
    ASSERT_TRUE(none.count("misfit:gabor"));
    const double gabor = none.at("misfit:gabor");
    ASSERT_GT(gabor, 0.0);
    EXPECT_EQ(none.count("misfit:field-start"), 1u);
    EXPECT_EQ(none.count("misfit:field-floor"), 0u);
    const Heightfield b = run(0.1 * gabor, &low);  // gabor > 0.1 × floor: the start decides
    EXPECT_EQ(low.count("misfit:field-start"), 1u);
    EXPECT_EQ(low.count("misfit:field-floor"), 0u);
    const Heightfield d = run(100.0 * gabor, &high);  // gabor < 0.1 × floor: skipped at once
    EXPECT_EQ(high.count("misfit:field-start"), 0u);
    EXPECT_EQ(high.count("refine:field"), 0u);
    EXPECT_EQ(high.at("misfit:field-floor"), 100.0 * gabor);
    EXPECT_EQ(high.count("select:gabor"), 1u);
    EXPECT_EQ(d.values(), refined.values());
    EXPECT_EQ(a.values(), b.values());
}

namespace {

// small_scalar_case's Gabor slices with Poisson noise of `photons` per slice.
ScalarCase noisy_gabor_case(std::uint64_t seed, double photons) {
    ScalarCase c = small_scalar_case(Simulator::Gabor, seed);
    add_noise(c.observations, Noise{NoiseKind::Poisson, photons}, seed + 1);
    return c;
}

// The truth's heights plus a smooth bump of `amplitude` µm: a fit that is off.
Heightfield off_by(const Heightfield& truth, double amplitude_um) {
    std::vector<double> v = truth.values();
    const double to_values = 1.0 / (truth.vscale() * truth.texel_um());
    for (int i = 0; i < truth.rows(); ++i)
        for (int j = 0; j < truth.cols(); ++j)
            v[std::size_t(i) * truth.cols() + j] +=
                amplitude_um * to_values * std::sin(2.0 * M_PI * i / truth.rows()) * std::cos(2.0 * M_PI * j / truth.cols());
    return truth.with_values(std::move(v));
}

}  // namespace

// The convergence check's floor rule, which the model check shares: above the floor only by
// both the ratio (1.05) and five standard deviations.
TEST(ModelCheck, PhotonFloorRule) {
    EXPECT_TRUE(misfit_on_photon_floor(1000.0, 1000.0, 10.0));
    EXPECT_TRUE(misfit_on_photon_floor(1040.0, 1000.0, 1.0));   // within the ratio
    EXPECT_TRUE(misfit_on_photon_floor(1100.0, 1000.0, 30.0));  // within 5 sd
    EXPECT_FALSE(misfit_on_photon_floor(1100.0, 1000.0, 10.0));
    EXPECT_TRUE(misfit_on_photon_floor(900.0, 1000.0, 1.0));  // below: part of the noise fitted
}

// The Gabor deviance against the Poisson statistics it claims: at the truth, on slices drawn as
// Poisson counts of the truth's own slices, D lies within 5 sd of E[D]; on the noiseless slices
// it is 0 there (every count equal to its mean); and it is the convergence check's deviance of
// the same slices (an independent implementation: double forwards, ordered sums) to 1e-5.
TEST(ModelCheck, GaborPhotonDevianceFollowsPoissonStatistics) {
    const double photons = 1e4;
    const ScalarCase noisy = noisy_gabor_case(7101, photons);
    const ScalarCase clean = small_scalar_case(Simulator::Gabor, 7101);
    const Communicator& comm = serial_communicator();
    const SliceDeviance d =
        detail::gabor_photon_deviance(pointers(noisy.observations), queries_of(noisy.observations), noisy.truth,
                                      false, photons, comm);
    ASSERT_GT(d.expected, 0.0);
    ASSERT_GT(d.variance, 0.0);
    EXPECT_LT(std::abs(d.deviance - d.expected), 5.0 * std::sqrt(d.variance))
        << d.deviance << " against " << d.expected << " +- " << std::sqrt(d.variance);
    const SliceDeviance zero = detail::gabor_photon_deviance(
        pointers(clean.observations), queries_of(clean.observations), clean.truth, false, photons, comm);
    EXPECT_LT(zero.deviance, 1e-3 * zero.expected);
    const ConvergenceCheck check = check_convergence(noisy.observations, noisy.truth, photons, false, nullptr, comm);
    EXPECT_NEAR(d.deviance, check.deviance, 1e-5 * check.deviance);
    EXPECT_NEAR(d.expected, check.expected_deviance, 1e-5 * check.expected_deviance);
    EXPECT_THROW(detail::gabor_photon_deviance(pointers(noisy.observations), {}, noisy.truth, false, photons, comm),
                 std::invalid_argument);
}

// With photon counts (the refinement's Poisson loss) a Gabor fit on the noise floor is kept
// without building the field model ("misfit:gabor-noise" ≤ the floor rule, then
// "select:gabor": no "misfit:field-start", no field refinement), and the heights are the Gabor
// fit's. A fit off the floor (a 0.02 µm bump on ±0.5 µm) still goes on to the field model, and
// without photons (amplitude loss) the rule is not asked.
TEST(ModelCheck, AGaborFitOnThePhotonFloorIsKept) {
    const double photons = 1e4;
    const ScalarCase c = noisy_gabor_case(7102, photons);
    std::vector<std::size_t> index(c.observations.size());
    for (std::size_t k = 0; k < index.size(); ++k) index[k] = k;
    const Heightfield unwrapped = off_by(c.truth, 0.05);
    const auto run = [&](const Heightfield& refined, const Loss& loss, std::map<std::string, double>* stages) {
        detail::ModelCheckSettings s;  // the library's defaults
        s.iterations = 2;
        s.skip_ratio = 0.0;  // the field model's own shortcut never decides here
        s.loss = loss;
        return detail::check_model(
            pointers(c.observations), index, {}, 1.0, unwrapped, refined, 3, s,
            [&](const detail::StageId& stage, int, double value, const Heightfield*) {
                EXPECT_EQ(stage.kind, stage_kind(stage.name)) << stage.name;
                (*stages)[stage.name] = value;
                return true;
            },
            serial_communicator(), 0.0);
    };
    std::map<std::string, double> on_floor, off_floor, no_photons;
    const Loss poisson{LossKind::Poisson, 1.0, photons};
    const Heightfield kept = run(c.truth, poisson, &on_floor);
    ASSERT_EQ(on_floor.count("misfit:gabor-noise"), 1u);
    EXPECT_LT(on_floor.at("misfit:gabor-noise"), k_misfit_ratio_limit);
    EXPECT_GT(on_floor.at("misfit:gabor-noise"), 0.9);
    EXPECT_EQ(on_floor.count("select:gabor"), 1u);
    EXPECT_EQ(on_floor.count("misfit:field-start"), 0u);
    EXPECT_EQ(on_floor.count("refine:field"), 0u);
    EXPECT_EQ(kept.values(), c.truth.values());

    run(off_by(c.truth, 0.02), poisson, &off_floor);
    ASSERT_EQ(off_floor.count("misfit:gabor-noise"), 1u);
    EXPECT_GT(off_floor.at("misfit:gabor-noise"), k_misfit_ratio_limit);
    EXPECT_EQ(off_floor.count("misfit:field-start"), 1u);

    run(c.truth, Loss{LossKind::Amplitude, 1.0, 0.0}, &no_photons);
    EXPECT_EQ(no_photons.count("misfit:gabor-noise"), 0u);
    EXPECT_EQ(no_photons.count("misfit:field-start"), 1u);
}
