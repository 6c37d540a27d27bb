// Self-calibration (calibration.h): the settings' text, the simulated acquisition errors and
// the closed forms and searches the recovery stages use (calibration_detail.h).
#include "wavebrdf/calibration.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>
#include <string>
#include <stdexcept>

#include "core/random.h"
#include "recovery/calibration_detail.h"

namespace wavebrdf {

CalibrationSettings parse_calibration(const std::string& text, const std::string& name) {
    CalibrationSettings s;
    const auto fail = [&](const std::string& word) {
        throw std::invalid_argument(name + " '" + word +
                                    "' is unknown; expected positions, exposure, sigma, all or none");
    };
    if (text.size() > 256) fail(text.substr(0, 32) + "...");
    std::stringstream in(text);
    std::string word;
    int words = 0;
    bool all_or_none = false;
    while (std::getline(in, word, ',')) {
        ++words;
        if (word == "positions")
            s.positions = true;
        else if (word == "exposure")
            s.exposure = true;
        else if (word == "sigma")
            s.sigma = true;
        else if (word == "all") {
            s.positions = s.exposure = s.sigma = true;
            all_or_none = true;
        } else if (word == "none")
            all_or_none = true;
        else
            fail(word);
    }
    if (words == 0 || (!text.empty() && text.back() == ',')) fail(text);
    if (all_or_none && words > 1) fail(text);  // "all" and "none" stand alone
    return s;
}

std::string to_string(const CalibrationSettings& settings) {
    std::string out;
    const auto add = [&](bool on, const char* word) {
        if (!on) return;
        if (!out.empty()) out += ',';
        out += word;
    };
    add(settings.positions, "positions");
    add(settings.exposure, "exposure");
    add(settings.sigma, "sigma");
    return out.empty() ? "none" : out;
}

void check_acquisition_errors(const AcquisitionErrors& e, const std::string& prefix) {
    const auto fail = [&](std::string what, double value, const std::string& expected) {
        // A Python-style prefix ("simulate_") names the keyword: simulate_sigma_factor.
        if (!prefix.empty() && prefix.back() == '_') std::replace(what.begin(), what.end(), '-', '_');
        std::ostringstream v;
        v << value;
        throw std::invalid_argument(prefix + what + " " + v.str() + " is invalid; expected " + expected);
    };
    if (!(e.position_rms_texels >= 0.0 && e.position_rms_texels <= 10.0))
        fail("position-error-texels", e.position_rms_texels, "an rms in texels, 0 to 10");
    if (!(e.exposure_min >= 1e-3 && e.exposure_min <= 1e3))
        fail("exposure min", e.exposure_min, "a factor in [0.001, 1000]");
    if (!(e.exposure_max >= 1e-3 && e.exposure_max <= 1e3))
        fail("exposure max", e.exposure_max, "a factor in [0.001, 1000]");
    if (e.exposure_min > e.exposure_max) fail("exposure min", e.exposure_min, "at most the max");
    if (!(e.sigma_p_factor >= 0.25 && e.sigma_p_factor <= 4.0))
        fail("sigma-factor", e.sigma_p_factor, "a factor in [0.25, 4]");
}

std::array<double, 2> simulated_position_offset_um(const AcquisitionErrors& errors, std::size_t position,
                                                   double texel_um) {
    if (errors.position_rms_texels == 0.0) return {{0.0, 0.0}};
    std::mt19937_64 rng(detail::derive_seed(detail::derive_seed(errors.seed, 71), position));
    double n[2];
    detail::fill_standard_normal(n, 2, rng);
    const double rms_um = errors.position_rms_texels * texel_um;
    return {{rms_um * n[0], rms_um * n[1]}};
}

double simulated_exposure(const AcquisitionErrors& errors, std::size_t observation) {
    if (errors.exposure_min == errors.exposure_max) return errors.exposure_min;
    std::mt19937_64 rng(detail::derive_seed(detail::derive_seed(errors.seed, 73), observation));
    const double lo = std::log(errors.exposure_min), hi = std::log(errors.exposure_max);
    return std::exp(lo + (hi - lo) * detail::uniform01(rng));
}

namespace detail {

double slice_exposure(const float* model, const float* reference, std::size_t n) {
    double r = 0.0, f = 0.0;
    for (std::size_t k = 0; k < n; ++k) {
        r += std::max(double(reference[k]), 0.0);
        f += std::max(double(model[k]), 0.0);
    }
    return f > 0.0 ? r / f : 1.0;
}

void exposure_gradient(double exposure, const float* model, std::size_t n, std::vector<double>& d) {
    double f = 0.0, df = 0.0;
    for (std::size_t k = 0; k < n; ++k) {
        const double m = std::max(double(model[k]), 0.0);
        f += m;
        df += d[k] * m;
    }
    const double shift = f > 0.0 ? exposure * df / f : 0.0;
    for (std::size_t k = 0; k < n; ++k) d[k] = exposure * d[k] - (model[k] > 0.0f ? shift : 0.0);
}

double refine_sigma_scale(const std::function<double(double)>& loss_at,
                          const std::function<bool(int, double, double)>& after_round, double initial) {
    if (!(initial >= 0.25 && initial <= 4.0))
        throw std::domain_error("refine_sigma_scale: initial scale " + std::to_string(initial) +
                                " is invalid; expected a factor in [0.25, 4]");
    const double widths[k_sigma_rounds] = {std::log(1.5), 0.08, 0.02};
    const int evaluations[k_sigma_rounds] = {12, 8, 7};
    double t = std::log(initial);  // log s
    for (int round = 0; round < k_sigma_rounds; ++round) {
        const double lo = std::max(t - widths[round], std::log(0.25)), hi = std::min(t + widths[round], std::log(4.0));
        double value = 0.0;
        t = golden_section_minimum([&](double x) { return loss_at(std::exp(x)); }, lo, hi, evaluations[round], &value);
        if (!after_round(round, std::exp(t), value)) break;
    }
    return std::exp(t);
}

Calibration gathered_calibration(const Calibration& mine, const std::vector<std::size_t>& share, std::size_t total,
                                 const Communicator& comm) {
    if (comm.size() == 1) return mine;
    // Per observation of this rank: index, exposure, offset x, offset y (NaN where absent).
    const double nan = std::numeric_limits<double>::quiet_NaN();
    std::vector<double> packed;
    for (std::size_t k = 0; k < share.size(); ++k) {
        packed.push_back(double(share[k]));
        packed.push_back(k < mine.exposures.size() ? mine.exposures[k] : nan);
        const bool has = k < mine.position_offsets_um.size();
        packed.push_back(has ? mine.position_offsets_um[k][0] : nan);
        packed.push_back(has ? mine.position_offsets_um[k][1] : nan);
    }
    std::vector<double> flags{mine.exposures.empty() ? 0.0 : 1.0, mine.position_offsets_um.empty() ? 0.0 : 1.0};
    comm.allreduce_sum(flags);  // whether any rank has them (a rank's share may be empty)
    const std::vector<double> all = comm.gather(packed);
    Calibration out;
    out.sigma_p_scale = mine.sigma_p_scale;
    out.sigma_p_scale_fields = mine.sigma_p_scale_fields;
    if (!comm.is_root()) return out;
    if (flags[0] > 0.0) out.exposures.assign(total, nan);
    if (flags[1] > 0.0) out.position_offsets_um.assign(total, {{nan, nan}});
    for (std::size_t at = 0; at + 3 < all.size(); at += 4) {
        const std::size_t i = std::size_t(all[at]);
        if (i >= total) continue;
        if (flags[0] > 0.0) out.exposures[i] = all[at + 1];
        if (flags[1] > 0.0) out.position_offsets_um[i] = {{all[at + 2], all[at + 3]}};
    }
    return out;
}

std::string calibration_json(const CalibrationSettings& refined, const Calibration& estimate,
                             const Calibration* truth) {
    nlohmann::json j;
    j["refined"] = to_string(refined);
    j["sigma_p_scale"] = estimate.sigma_p_scale;
    if (refined.sigma) j["sigma_p_scale_fields"] = estimate.sigma_p_scale_fields;
    if (!estimate.exposures.empty()) j["exposures"] = estimate.exposures;
    if (!estimate.position_offsets_um.empty()) j["position_offsets_um"] = estimate.position_offsets_um;
    if (truth) {
        nlohmann::json t;
        t["sigma_p_scale"] = truth->sigma_p_scale;
        t["exposures"] = truth->exposures;
        t["position_offsets_um"] = truth->position_offsets_um;
        j["truth"] = t;
        nlohmann::json e;
        e["sigma_p_scale"] = estimate.sigma_p_scale / truth->sigma_p_scale - 1.0;
        if (!estimate.exposures.empty() && estimate.exposures.size() == truth->exposures.size()) {
            double sum = 0.0, worst = 0.0;
            for (std::size_t i = 0; i < truth->exposures.size(); ++i) {
                const double d = estimate.exposures[i] / truth->exposures[i] - 1.0;
                sum += d * d;
                worst = std::max(worst, std::abs(d));
            }
            e["exposure_rel_rms"] = std::sqrt(sum / double(truth->exposures.size()));
            e["exposure_rel_max"] = worst;
        }
        if (!estimate.position_offsets_um.empty() &&
            estimate.position_offsets_um.size() == truth->position_offsets_um.size()) {
            double sum = 0.0;
            for (std::size_t i = 0; i < truth->position_offsets_um.size(); ++i)
                for (int c = 0; c < 2; ++c) {
                    const double d = estimate.position_offsets_um[i][c] - truth->position_offsets_um[i][c];
                    sum += d * d;
                }
            e["position_rms_um"] = std::sqrt(sum / double(2 * truth->position_offsets_um.size()));
        }
        j["errors"] = e;
    }
    return j.dump(1) + "\n";
}

}  // namespace detail

}  // namespace wavebrdf

// (declared in recover.h, next to height_rel_rmse)
#include "wavebrdf/recover.h"

namespace wavebrdf {

double height_rel_rmse_plane_removed(const Heightfield& estimate, const Heightfield& truth) {
    if (estimate.rows() != truth.rows() || estimate.cols() != truth.cols())
        throw std::invalid_argument("height_rel_rmse_plane_removed: estimate is " + std::to_string(estimate.rows()) +
                                    " x " + std::to_string(estimate.cols()) + " but truth is " +
                                    std::to_string(truth.rows()) + " x " + std::to_string(truth.cols()));
    const int rows = truth.rows(), cols = truth.cols();
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (int i = 0; i < rows; ++i)
        for (int j = 0; j < cols; ++j) {
            lo = std::min(lo, truth.height_um(i, j));
            hi = std::max(hi, truth.height_um(i, j));
        }
    if (!(hi > lo)) throw std::domain_error("height_rel_rmse_plane_removed: the truth is flat; its height range is 0");
    // Least squares a + b x + c y on the texel centres, x and y centred on the tile: on the full
    // grid 1, x and y are orthogonal, so each coefficient is a projection.
    const double cx = 0.5 * (rows - 1), cy = 0.5 * (cols - 1);
    double sum = 0.0, sum_x = 0.0, sum_y = 0.0, xx = 0.0, yy = 0.0;
    for (int i = 0; i < rows; ++i)
        for (int j = 0; j < cols; ++j) {
            const double d = estimate.height_um(i, j) - truth.height_um(i, j);
            const double x = i - cx, y = j - cy;
            sum += d;
            sum_x += d * x;
            sum_y += d * y;
            xx += x * x;
            yy += y * y;
        }
    const double n = double(rows) * cols;
    const double a = sum / n, b = xx > 0.0 ? sum_x / xx : 0.0, c = yy > 0.0 ? sum_y / yy : 0.0;
    double rss = 0.0;
    for (int i = 0; i < rows; ++i)
        for (int j = 0; j < cols; ++j) {
            const double d = estimate.height_um(i, j) - truth.height_um(i, j) - (a + b * (i - cx) + c * (j - cy));
            rss += d * d;
        }
    return std::sqrt(rss / n) / (hi - lo);
}

}  // namespace wavebrdf
