// Recovery study (issue 5, item 4): generate a fresh isotropic truth, plan jittered
// overlapping positions at several wavelengths, render the observations, recover the heights
// from a flat start (recover_heights), and optionally run the thesis's baseline (Adam on the
// log loss, one observation per epoch) on the same data.
//
//   recover_study [key=value ...]
//     size=32 texel_um=2 corr_texels=4 max_height_um=1 seed=1
//     sigma_p_um=3 step_um=3 jitter=0.2 resolution=96 lambdas=0.5,0.55,0.65
//     (recovery, defaults from RecoverSettings:) refine blur_iters blurs=16,8,4 blur_wavelengths
//     field_iters refine_iters max_range_um field_lambda_min_um
//     (baselines on the same data:) baseline_epochs=0 direct_iters=0   quiet=0
//     (self-calibration:) planner=0 (1: plan_acquisition's positions, σ_p and wavelengths at
//     `resolution`, seeded by seed) position_error_texels=0 (each position's true centre off by a
//     Gaussian of this rms per coordinate, all wavelengths alike; the recovery gets the stated
//     ones) zero_mean_errors=0 (1: the drawn offsets' mean removed) calibrate=none|positions
//     (position outer loop:) outer_passes outer_tolerance
//     outer_field_iters=20 outer_refine_iters=0 (later passes' iterations; 0: the
//     first's) register_check=0 (1: after the run, register every position at the final
//     heights from the calibrated offsets and print the offsets' error before and after: REGISTER)
//     save=PREFIX (write PREFIX_estimate.npy and PREFIX_truth.npy, heights in µm, for analysis)
//     warp_metric=1 (the WARP
//     line: the error on the inner texels with the best-fit translation / 6 × 6-node warp of the
//     truth removed, a diagnostic beside rel_rmse)
//     stall_diag=0 (per-position table, PREFIX_positions.csv)
//     rescue_factor=20 rescue_radius=4 rescue_step=radius/32 (positions with loss > factor ×
//     median searched ± radius, coarse grid 2·step; 0: off)
//     field_below=0.05 (a later pass skips the field stage when its registration moved < this)
//     stall_passes=2 stall_tolerance=0.02 (the stall rule, core/stall_rule.h, over passes; 0: off)
//     stall_median=1 (the rule on the median position's loss at the start of a pass; 0:
//     on stage 3's loss)
//     (the outer loop's knobs default to the schedule's, PositionLoopSettings in stages.h; the
//     loop is on with calibrate=positions; outer_passes and rescue_radius are RecoverSettings')
//   Options of studies whose alternative left the library (the default kept, as a constant):
//   unwrap=blurred, cascade=0, field_passes, blur_spacing, register_radius, outer_fields,
//   outer_smooth, rescue_centre, register_newton, newton_step, newton_cap, exposures_held; their
//   measurements are in experiments/2026-11-23-position-calibration.md and recover_study.md.
// Prints one line per reported step (stage, iteration, loss, seconds, height_rel_rmse) unless
// quiet, then a summary line "RESULT key=value ...".
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <functional>
#include <map>
#include <numeric>
#include <memory>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "wavebrdf/acquisition.h"
#include "wavebrdf/baseline.h"
#include "wavebrdf/calibration.h"
#include "wavebrdf/generate.h"
#include "wavebrdf/io.h"
#include "wavebrdf/optim.h"
#include "core/catmull_rom.h"
#include "recovery/field_positions.h"
#include "recovery/recover_positions.h"
#include "recovery/stages.h"
#include "wavebrdf/recover.h"
#include "wavebrdf/loss.h"
#include "wavebrdf/slice_plan.h"

using namespace wavebrdf;

namespace {

std::map<std::string, std::string> parse(int argc, char** argv) {
    std::map<std::string, std::string> m;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        const auto eq = a.find('=');
        if (eq == std::string::npos) throw std::invalid_argument("argument '" + a + "': expected key=value");
        m[a.substr(0, eq)] = a.substr(eq + 1);
    }
    return m;
}

std::vector<double> parse_list(const std::string& s) {
    std::vector<double> v;
    std::stringstream ss(s);
    std::string item;
    while (std::getline(ss, item, ',')) v.push_back(std::stod(item));
    return v;
}

// Catmull-Rom bicubic sample of a rows × cols grid at (r, c) (texels; the grid clamped at its
// edges).
double cubic_sample(const std::vector<double>& a, int rows, int cols, double r, double c) {
    const auto at = [&](int i, int j) {
        i = std::min(rows - 1, std::max(0, i));
        j = std::min(cols - 1, std::max(0, j));
        return a[std::size_t(i) * cols + j];
    };
    return detail::catmull_rom_bicubic(r, c, at);
}

// Round 8 (docs/recovery.md, "Self-calibration: positions"): height_rel_rmse's kind of figure
// (% of the truth's range, mean removed) on the inner texels (margin texels left out) after the
// best-fit smooth warp of the truth: a displacement bilinear on k × k nodes (texels; k = 1: a
// translation) maps the truth (bicubic) onto the estimate, Gauss–Newton from 0 (as
// experiments/warp_fit.py, with Catmull-Rom for scipy's spline). A diagnostic of how much of the
// error is a smooth warp (positions and heights moved together), not the target.
double warp_removed_rel_rmse(const std::vector<double>& e, const std::vector<double>& t, int rows, int cols, int k,
                             int margin, double* warp_rms_texels) {
    double lo = t[0], hi = t[0];
    for (double v : t) {
        lo = std::min(lo, v);
        hi = std::max(hi, v);
    }
    const int m = 2 * k * k + 1;  // dx, dy per node, and the mean
    std::vector<double> p(m, 0.0);
    const auto node_weights = [&](int i, int j, std::vector<std::pair<int, double>>& out) {
        out.clear();
        if (k == 1) {
            out.push_back({0, 1.0});
            return;
        }
        const double u = double(i) * (k - 1) / std::max(1, rows - 1), v = double(j) * (k - 1) / std::max(1, cols - 1);
        const int a = std::min(k - 2, int(std::floor(u))), b = std::min(k - 2, int(std::floor(v)));
        const double fu = u - a, fv = v - b;
        out.push_back({a * k + b, (1 - fu) * (1 - fv)});
        out.push_back({(a + 1) * k + b, fu * (1 - fv)});
        out.push_back({a * k + b + 1, (1 - fu) * fv});
        out.push_back({(a + 1) * k + b + 1, fu * fv});
    };
    std::vector<std::pair<int, double>> nw;
    double rel = 0.0;
    for (int iter = 0; iter <= 12; ++iter) {
        std::vector<double> jtj(std::size_t(m) * m, 0.0), jtr(m, 0.0);
        double r2 = 0.0, rsum = 0.0, count = 0.0;
        for (int i = margin; i < rows - margin; ++i)
            for (int j = margin; j < cols - margin; ++j) {
                node_weights(i, j, nw);
                double dx = 0.0, dy = 0.0;  // dx along the columns, dy along the rows
                for (const auto& [n, wgt] : nw) {
                    dx += wgt * p[n];
                    dy += wgt * p[k * k + n];
                }
                const double r0 = i + dy, c0 = j + dx, h = 1e-3;
                const double tw = cubic_sample(t, rows, cols, r0, c0);
                const double gr = (cubic_sample(t, rows, cols, r0 + h, c0) - cubic_sample(t, rows, cols, r0 - h, c0)) /
                                  (2 * h);
                const double gc = (cubic_sample(t, rows, cols, r0, c0 + h) - cubic_sample(t, rows, cols, r0, c0 - h)) /
                                  (2 * h);
                const double res = e[std::size_t(i) * cols + j] - tw - p[m - 1];
                r2 += res * res;
                rsum += res;
                count += 1.0;
                // Jacobian of tw + mean with respect to the parameters.
                std::vector<std::pair<int, double>> jac;
                for (const auto& [n, wgt] : nw) {
                    jac.push_back({n, gc * wgt});
                    jac.push_back({k * k + n, gr * wgt});
                }
                jac.push_back({m - 1, 1.0});
                for (const auto& [a, ja] : jac) {
                    jtr[a] += ja * res;
                    for (const auto& [b, jb] : jac) jtj[std::size_t(a) * m + b] += ja * jb;
                }
            }
        const double mean = rsum / count;
        rel = std::sqrt(std::max(0.0, r2 / count - mean * mean)) / (hi - lo) * 100.0;
        if (iter == 12) break;
        double trace = 0.0;
        for (int a = 0; a < m; ++a) trace += jtj[std::size_t(a) * m + a];
        for (int a = 0; a < m; ++a) jtj[std::size_t(a) * m + a] += 1e-9 * trace / m;
        // Cholesky solve jtj · step = jtr.
        std::vector<double>& A = jtj;
        for (int j = 0; j < m; ++j) {
            for (int q = 0; q < j; ++q)
                A[std::size_t(j) * m + j] -= A[std::size_t(j) * m + q] * A[std::size_t(j) * m + q];
            A[std::size_t(j) * m + j] = std::sqrt(A[std::size_t(j) * m + j]);
            for (int i = j + 1; i < m; ++i) {
                for (int q = 0; q < j; ++q)
                    A[std::size_t(i) * m + j] -= A[std::size_t(i) * m + q] * A[std::size_t(j) * m + q];
                A[std::size_t(i) * m + j] /= A[std::size_t(j) * m + j];
            }
        }
        std::vector<double> x = jtr;
        for (int i = 0; i < m; ++i) {
            for (int q = 0; q < i; ++q) x[i] -= A[std::size_t(i) * m + q] * x[q];
            x[i] /= A[std::size_t(i) * m + i];
        }
        for (int i = m - 1; i >= 0; --i) {
            for (int q = i + 1; q < m; ++q) x[i] -= A[std::size_t(q) * m + i] * x[q];
            x[i] /= A[std::size_t(i) * m + i];
        }
        for (int a = 0; a < m; ++a) p[a] += x[a];
    }
    if (warp_rms_texels) {
        double s = 0.0;
        for (int i = 0; i < rows; ++i)
            for (int j = 0; j < cols; ++j) {
                node_weights(i, j, nw);
                double dx = 0.0, dy = 0.0;
                for (const auto& [n, wgt] : nw) {
                    dx += wgt * p[n];
                    dy += wgt * p[k * k + n];
                }
                s += dx * dx + dy * dy;
            }
        *warp_rms_texels = std::sqrt(s / (double(rows) * cols));
    }
    return rel;
}

}  // namespace

int main(int argc, char** argv) try {
    std::setvbuf(stdout, nullptr, _IOLBF, 0);
    auto args = parse(argc, argv);
    const auto get = [&](const char* key, const char* def) {
        auto it = args.find(key);
        return it == args.end() ? std::string(def) : it->second;
    };
    const int size = std::stoi(get("size", "32"));
    const double texel_um = std::stod(get("texel_um", "2"));
    const double corr_texels = std::stod(get("corr_texels", "4"));
    const double max_height_um = std::stod(get("max_height_um", "1"));
    const auto seed = std::stoull(get("seed", "1"));
    const double sigma_p_um = std::stod(get("sigma_p_um", "3"));
    const double step_um = std::stod(get("step_um", "3"));
    const double jitter = std::stod(get("jitter", "0.2"));
    const int resolution = std::stoi(get("resolution", "96"));
    const std::vector<double> lambdas = parse_list(get("lambdas", "0.5,0.55,0.65"));
    const int baseline_epochs = std::stoi(get("baseline_epochs", "0"));
    const bool quiet = get("quiet", "0") == "1";

    // Truth: isotropic Gaussian-correlated heights, mean 0, scaled so max |H| = max_height_um.
    SurfaceParams sp;
    sp.type = SurfaceType::Isotropic;
    sp.rows = sp.cols = size;
    sp.texel_um = texel_um;
    sp.seed = seed;
    sp.rms_height_um = 1.0;
    sp.correlation_um = corr_texels * texel_um;
    Heightfield raw = generate_heightfield(sp);
    double peak = 0.0;
    for (double v : raw.values()) peak = std::max(peak, std::abs(v));
    std::vector<double> scaled = raw.values();
    for (double& v : scaled) v *= max_height_um / (peak * texel_um);
    const Heightfield truth = raw.with_values(scaled);
    const HeightStats stats = height_stats(truth);

    // Positions: a raster of step_um, each jittered uniformly by ±jitter·step.
    std::mt19937_64 rng(seed * 7919 + 17);
    std::uniform_real_distribution<double> uni(-1.0, 1.0);
    const double period = size * texel_um;
    const int steps = std::max(1, int(std::lround(period / step_um)));
    const double step = period / steps;
    std::vector<Observation> observations;
    std::vector<std::array<double, 2>> positions;
    double sigma_p = sigma_p_um;
    std::vector<double> lambdas_used = lambdas;
    if (get("planner", "0") == "1") {
        PlanRequest request;
        request.rows = request.cols = size;
        request.texel_um = texel_um;
        request.height_range_um = stats.max_um - stats.min_um;
        request.resolution = resolution;
        request.seed = seed;
        const AcquisitionPlan plan = plan_acquisition(request);
        positions = plan.positions_um;
        sigma_p = plan.sigma_p_um;
        lambdas_used = plan.lambdas_um;
    } else {
        for (int a = 0; a < steps; ++a)
            for (int b = 0; b < steps; ++b)
                positions.push_back(
                    {(a + 0.5) * step + jitter * step * uni(rng), (b + 0.5) * step + jitter * step * uni(rng)});
    }
    // Position errors: the true centre = stated + error (per position, all wavelengths alike).
    const double error_texels = std::stod(get("position_error_texels", "0"));
    std::vector<std::array<double, 2>> errors(positions.size(), {0.0, 0.0});
    {
        std::mt19937_64 err_rng(seed * 104729 + 5);
        std::normal_distribution<double> normal(0.0, error_texels * texel_um);
        for (auto& e : errors) e = {normal(err_rng), normal(err_rng)};
        if (get("zero_mean_errors", "0") == "1") {
            std::array<double, 2> mean{0.0, 0.0};
            for (const auto& e : errors)
                mean = {mean[0] + e[0] / double(errors.size()), mean[1] + e[1] / double(errors.size())};
            for (auto& e : errors) e = {e[0] - mean[0], e[1] - mean[1]};
        }
    }
    std::vector<std::array<double, 2>> obs_error;  // per observation
    const auto t_render = std::chrono::steady_clock::now();
    for (double lambda : lambdas_used)
        for (std::size_t k = 0; k < positions.size(); ++k) {
            const auto& p = positions[k];
            Observation o;
            o.query.x_um = p[0] + errors[k][0];
            o.query.y_um = p[1] + errors[k][1];
            o.query.sigma_p_um = sigma_p;
            o.lambdas_um = {lambda};
            o.resolution = resolution;
            o.reference = to_reference(render_observation(truth, o));
            o.query.x_um = p[0];  // the recovery gets the stated centre
            o.query.y_um = p[1];
            observations.push_back(std::move(o));
            obs_error.push_back(errors[k]);
        }
    const double render_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_render).count();
    if (!quiet)
        std::printf(
            "truth %dx%d texel %g um: rms %.3f um, range [%.3f, %.3f] um, rms slope %.3f; %zu positions "
            "(step %.2f um), %zu observations rendered in %.1f s\n",
            size, size, texel_um, stats.rms_height_um, stats.min_um, stats.max_um, stats.rms_slope, positions.size(),
            step, observations.size(), render_s);

    // The library's defaults unless a key overrides them.
    RecoverSettings rs;
    const auto set_int = [&](const char* key, int& value) {
        if (args.count(key)) value = std::stoi(args[key]);
    };
    set_int("refine", rs.refine);
    set_int("field_iters", rs.field.iterations);
    set_int("blur_iters", rs.blurred.iterations);
    set_int("blur_wavelengths", rs.blur_wavelengths);
    set_int("refine_iters", rs.refine_iterations);
    if (args.count("blurs")) rs.blurred.blur_widths = parse_list(args["blurs"]);
    set_int("outer_passes", rs.position_outer_passes);
    if (args.count("max_range_um")) rs.height_range_um = std::stod(args["max_range_um"]);
    if (args.count("field_lambda_min_um")) rs.field_lambda_min_um = std::stod(args["field_lambda_min_um"]);
    rs.calibrate.positions = get("calibrate", "none") == "positions";  // (parse_calibration: CAL)
    if (args.count("rescue_radius")) rs.position_rescue_radius_texels = std::stod(args["rescue_radius"]);
    // The position loop's own settings (stages.h, PositionLoopSettings): the schedule's unless a
    // key overrides them.
    std::map<std::string, std::string> loop_args;
    for (const char* key : {"outer_tolerance", "outer_field_iters", "outer_refine_iters", "rescue_factor",
                            "rescue_step", "stall_passes", "stall_tolerance", "field_below", "stall_median"})
        if (args.count(key)) loop_args[key] = args[key];
    const auto edit = [loop_args](detail::Schedule& schedule) {
        detail::edit_stages<detail::PositionLoopStage>(schedule, [&](detail::PositionLoopStage& stage) {
            detail::PositionLoopSettings& p = stage.settings;
            for (const auto& [key, value] : loop_args) {
                if (key == "outer_tolerance") p.tolerance_texels = std::stod(value);
                if (key == "outer_field_iters") p.field_iterations = std::stoi(value);
                if (key == "outer_refine_iters") p.refine_iterations = std::stoi(value);
                if (key == "rescue_factor") p.rescue_factor = std::stod(value);
                if (key == "rescue_step") p.rescue_step_texels = std::stod(value);
                if (key == "stall_passes") p.stall_passes = std::stoi(value);
                if (key == "stall_tolerance") p.stall_tolerance = std::stod(value);
                if (key == "field_below") p.field_below_texels = std::stod(value);
                if (key == "stall_median") p.stall_median = value == "1";
            }
        });
    };
    Calibration calibration;
    double blur_s = 0, blur_rmse = -1, field_s = 0, unwrap_rmse = -1, field_end = 0;
    std::string last_stage;
    const Heightfield estimate = detail::recover_heights_edited(
        observations, size, size, texel_um, 1.0, rs, edit,
        [&](const StageMetrics& m) {
            if (m.stage == "blur") {
                blur_rmse = m.height_rel_rmse;
                blur_s = m.seconds;
            }
            if (m.stage == "unwrap") {
                unwrap_rmse = m.height_rel_rmse;
                field_s = m.seconds;
            }
            if (!quiet && (m.stage != last_stage || m.iteration % 10 == 0))
                std::printf("%-12s %4d loss %.4e  %6.1f s  rel_rmse %.5f\n", m.stage.c_str(), m.iteration, m.loss,
                            m.seconds, m.height_rel_rmse);
            last_stage = m.stage;
            field_end = m.seconds;
            return true;
        },
        &truth, serial_communicator(), &calibration);
    const double rel = height_rel_rmse(estimate, truth);
    detail::PositionFitSettings fit;  // what the registration reads of rs (the diagnostics below)
    fit.loss = rs.refine_loss;
    fit.calibrate_exposure = rs.calibrate.exposure;
    if (args.count("save")) {
        const std::vector<std::size_t> shape{std::size_t(truth.rows()), std::size_t(truth.cols())};
        write_npy(args["save"] + "_estimate.npy", shape, heights_um(estimate));
        write_npy(args["save"] + "_truth.npy", shape, heights_um(truth));
    }
    // Position calibration: rms of (found − true) after removing each one's mean, texels.
    if (!calibration.position_offsets_um.empty()) {
        std::array<double, 2> mt{0, 0}, mf{0, 0};
        const double n = double(obs_error.size());
        for (std::size_t i = 0; i < obs_error.size(); ++i)
            for (int c = 0; c < 2; ++c) {
                mt[c] += obs_error[i][c] / n;
                mf[c] += calibration.position_offsets_um[i][c] / n;
            }
        double e2 = 0.0, t2 = 0.0;
        for (std::size_t i = 0; i < obs_error.size(); ++i)
            for (int c = 0; c < 2; ++c) {
                const double t = obs_error[i][c] - mt[c];
                const double d = calibration.position_offsets_um[i][c] - mf[c] - t;
                e2 += d * d;
                t2 += t * t;
            }
        std::printf("POSITIONS error_rms_texels=%.4f calibrated_rms_texels=%.4f mean_error_texels=(%.4f, %.4f)\n",
                    std::sqrt(t2 / (2 * n)) / texel_um, std::sqrt(e2 / (2 * n)) / texel_um, mt[0] / texel_um,
                    mt[1] / texel_um);
        // register_check=1: every position registered at the final heights (the outer loop's
        // registration, recover_positions.h) from the calibrated offsets, and its error.
        if (get("register_check", "0") == "1") {
            std::vector<std::size_t> index;
            const std::size_t count = detail::gather_positions(observations, index, serial_communicator()).size();
            std::vector<double> off(2 * count, 0.0);
            for (std::size_t i = 0; i < index.size(); ++i)
                for (int c = 0; c < 2; ++c) off[2 * index[i] + c] = calibration.position_offsets_um[i][c];
            const auto error_rms = [&](const std::vector<double>& o) {
                std::array<double, 2> m{0, 0};
                for (std::size_t i = 0; i < index.size(); ++i)
                    for (int c = 0; c < 2; ++c) m[c] += o[2 * index[i] + c] / n;
                double s2 = 0.0;
                for (std::size_t i = 0; i < index.size(); ++i)
                    for (int c = 0; c < 2; ++c) {
                        const double d = o[2 * index[i] + c] - m[c] - (obs_error[i][c] - mt[c]);
                        s2 += d * d;
                    }
                return std::sqrt(s2 / (2 * n)) / texel_um;
            };
            const double radius = std::stod(get("register_radius", "2"));
            const double moved = detail::register_positions(
                observations, index, estimate, fit, calibration.sigma_p_scale > 0 ? calibration.sigma_p_scale : 1.0,
                radius, 0.5, off, serial_communicator());
            std::printf(
                "REGISTER radius_texels=%g moved_rms_texels=%.4f before_rms_texels=%.4f "
                "after_rms_texels=%.4f\n",
                radius, moved, std::sqrt(e2 / (2 * n)) / texel_um, error_rms(off));
        }
    }
    // Round 10: stall_diag=1 — which positions hold the stall (docs/recovery.md, "Self-calibration:
    // positions", round 10). Per gathered position, at the final heights and at the true heights:
    // the loss (sum over its observations, settings.refine_loss, σ_p × the calibrated scale) at the
    // found offsets, at the true offsets (the found mean added: the gauge) and at the registered
    // ones (register_positions from the found offsets at the final heights), the 2 × 2 Hessian of
    // the loss in the offset at the found offsets (central differences, step h texels) and the
    // distance of the stated centre to the raster's border. PREFIX_positions.csv (with save=).
    if (!calibration.position_offsets_um.empty() && get("stall_diag", "0") == "1") {
        std::vector<std::size_t> index;
        const std::vector<std::array<double, 2>> centres = detail::gather_positions(observations, index,
                                                                                    serial_communicator());
        const std::size_t count = centres.size();
        std::vector<double> found(2 * count, 0.0), truth_off(2 * count, 0.0);
        std::array<double, 2> mf{0, 0}, mt{0, 0};
        for (std::size_t i = 0; i < index.size(); ++i)
            for (int c = 0; c < 2; ++c) {
                found[2 * index[i] + c] = calibration.position_offsets_um[i][c];
                truth_off[2 * index[i] + c] = obs_error[i][c];
            }
        for (std::size_t p = 0; p < count; ++p)
            for (int c = 0; c < 2; ++c) {
                mf[c] += found[2 * p + c] / double(count);
                mt[c] += truth_off[2 * p + c] / double(count);
            }
        const double sigma_scale = calibration.sigma_p_scale > 0 ? calibration.sigma_p_scale : 1.0;
        const double h = std::stod(get("diag_step", "0.25"));
        const double radius = std::stod(get("register_radius", "2"));
        std::vector<double> registered = found;
        detail::register_positions(observations, index, estimate, fit, sigma_scale, radius, 0.5, registered,
                                   serial_communicator());
        detail::newton_register_positions(observations, index, estimate, fit, sigma_scale, detail::k_newton_step_texels,
                                          detail::k_newton_cap_texels, registered, serial_communicator());
        // loss(heights, offsets per position (µm), shift in texels) per position.
        const auto losses = [&](const Heightfield& hf, const std::vector<double>& off, double sx, double sy) {
            std::vector<double> l(count, 0.0);
            for (std::size_t i = 0; i < observations.size(); ++i) {
                const Observation& o = observations[i];
                const std::size_t p = index[i];
                Query q = o.query;
                q.x_um += off[2 * p] + texel_um * sx;
                q.y_um += off[2 * p + 1] + texel_um * sy;
                q.sigma_p_um *= sigma_scale;
                SlicePlan<float> plan(hf, q, o.lambdas_um, o.resolution, o.channels(), {}, false);
                const std::vector<float>& f = plan.forward();
                const std::vector<double> model(f.begin(), f.end());
                l[p] += loss_value(rs.refine_loss, model, o.reference, o.channels(), nullptr) /
                        double(observations.size());
            }
            return l;
        };
        // Truth in the found offsets' gauge at the final heights (the recovery fixes the mean).
        std::vector<double> truth_gauged = truth_off, found_abs = found;
        for (std::size_t p = 0; p < count; ++p)
            for (int c = 0; c < 2; ++c) {
                truth_gauged[2 * p + c] += mf[c] - mt[c];
                found_abs[2 * p + c] += mt[c] - mf[c];
            }
        const std::vector<double> lf_found = losses(estimate, found, 0, 0);
        const std::vector<double> lf_true = losses(estimate, truth_gauged, 0, 0);
        const std::vector<double> lf_reg = losses(estimate, registered, 0, 0);
        const std::vector<double> lt_found = losses(truth, found_abs, 0, 0);
        const std::vector<double> lt_true = losses(truth, truth_off, 0, 0);
        const std::vector<double> xp = losses(estimate, found, h, 0), xm = losses(estimate, found, -h, 0);
        const std::vector<double> yp = losses(estimate, found, 0, h), ym = losses(estimate, found, 0, -h);
        const std::vector<double> pp = losses(estimate, found, h, h), pm = losses(estimate, found, h, -h);
        const std::vector<double> mp = losses(estimate, found, -h, h), mm = losses(estimate, found, -h, -h);
        FILE* csv = nullptr;
        if (args.count("save")) csv = std::fopen((args["save"] + "_positions.csv").c_str(), "w");
        if (csv)
            std::fprintf(csv,
                         "p,cx_um,cy_um,edge_texels,true_dx,true_dy,found_dx,found_dy,reg_dx,reg_dy,err_found,err_reg,"
                         "gx,gy,hxx,hxy,hyy,lmin,lmax,newton_err,lf_found,lf_true,lf_reg,lt_found,lt_true\n");
        const double period_um = size * texel_um;
        double sum_ff = 0, sum_ft = 0, sum_fr = 0, sum_tf = 0, sum_tt = 0;
        int true_lower = 0;
        for (std::size_t p = 0; p < count; ++p) {
            const double cx = centres[p][0], cy = centres[p][1];
            const double edge = std::min({cx, period_um - cx, cy, period_um - cy}) / texel_um;
            const double tdx = (truth_gauged[2 * p] - mf[0]) / texel_um,
                         tdy = (truth_gauged[2 * p + 1] - mf[1]) / texel_um;
            const double fdx = (found[2 * p] - mf[0]) / texel_um, fdy = (found[2 * p + 1] - mf[1]) / texel_um;
            const double rdx = (registered[2 * p] - mf[0]) / texel_um, rdy = (registered[2 * p + 1] - mf[1]) / texel_um;
            const double ef = std::hypot(fdx - tdx, fdy - tdy), er = std::hypot(rdx - tdx, rdy - tdy);
            const double gx = (xp[p] - xm[p]) / (2 * h), gy = (yp[p] - ym[p]) / (2 * h);
            const double hxx = (xp[p] - 2 * lf_found[p] + xm[p]) / (h * h);
            const double hyy = (yp[p] - 2 * lf_found[p] + ym[p]) / (h * h);
            const double hxy = (pp[p] - pm[p] - mp[p] + mm[p]) / (4 * h * h);
            const double tr = 0.5 * (hxx + hyy), dis = std::sqrt(0.25 * (hxx - hyy) * (hxx - hyy) + hxy * hxy);
            // The Newton point of the quadratic model about the found offsets: its error.
            const double det = hxx * hyy - hxy * hxy;
            double ndx = fdx, ndy = fdy;
            if (det > 0 && hxx > 0) {
                ndx -= (hyy * gx - hxy * gy) / det;
                ndy -= (-hxy * gx + hxx * gy) / det;
            }
            const double en = std::hypot(ndx - tdx, ndy - tdy);
            sum_ff += lf_found[p];
            sum_ft += lf_true[p];
            sum_fr += lf_reg[p];
            sum_tf += lt_found[p];
            sum_tt += lt_true[p];
            true_lower += lf_true[p] < lf_found[p];
            if (csv)
                std::fprintf(csv,
                             "%zu,%.6f,%.6f,%.4f,%.6f,%.6f,%.6f,%.6f,%.6f,%.6f,%.6f,%.6f,%.6e,%.6e,%.6e,%.6e,%.6e,%.6e,"
                             "%.6e,%.6f,%.6e,%.6e,%.6e,%.6e,%.6e\n",
                             p, cx, cy, edge, tdx, tdy, fdx, fdy, rdx, rdy, ef, er, gx, gy, hxx, hxy, hyy, tr - dis,
                             tr + dis, en, lf_found[p], lf_true[p], lf_reg[p], lt_found[p], lt_true[p]);
        }
        if (csv) std::fclose(csv);
        std::printf(
            "STALLDIAG positions=%zu final_heights: loss_found=%.6e loss_true=%.6e loss_registered=%.6e "
            "true_lower_at=%d true_heights: loss_found=%.6e loss_true=%.6e\n",
            count, sum_ff, sum_ft, sum_fr, true_lower, sum_tf, sum_tt);
    }
    std::printf(
        "RESULT size=%d texel_um=%g corr_texels=%g sigma_p_um=%g step_um=%.3f positions=%zu resolution=%d "
        "lambdas=%s blur_rel_rmse=%.5f blur_s=%.1f unwrap_rel_rmse=%.5f field_unwrap_s=%.1f total_s=%.1f "
        "rel_rmse=%.5f\n",
        size, texel_um, corr_texels, sigma_p_um, step, positions.size(), resolution,
        get("lambdas", "0.5,0.55,0.65").c_str(), blur_rmse, blur_s, unwrap_rmse, field_s, field_end, rel);

    // The warp-removed figure beside rel_rmse (a diagnostic; the target stays rel_rmse).
    if (get("warp_metric", "1") == "1") {
        const std::vector<double> e = heights_um(estimate), t = heights_um(truth);
        double warp0 = 0.0, warp6 = 0.0;
        const double inner = warp_removed_rel_rmse(e, t, truth.rows(), truth.cols(), 1, 3, &warp0);
        const double removed = warp_removed_rel_rmse(e, t, truth.rows(), truth.cols(), 6, 3, &warp6);
        std::printf(
            "WARP inner_translation_removed_rel_rmse=%.5f translation_texels=%.4f warp6_removed_rel_rmse=%.5f "
            "warp6_rms_texels=%.4f\n",
            inner / 100.0, warp0, removed / 100.0, warp6);
    }

    if (baseline_epochs > 0) {
        // The thesis's method on the same observations (baseline.h): Adam (lr 0.01, β 0.9/0.99,
        // decay 0.005 per epoch), CMSLE ε = 1, one observation drawn at random per epoch, from flat.
        BaselineSettings settings;
        settings.epochs = baseline_epochs;
        settings.seed = seed;
        settings.report_every = 100;
        const auto t0 = std::chrono::steady_clock::now();
        double best = INFINITY;
        const Heightfield h = recover_heights_thesis(
            observations, truth.rows(), truth.cols(), truth.texel_um(), truth.vscale(), settings,
            [&](const StageMetrics& m) {
                best = std::min(best, m.height_rel_rmse);
                return true;
            },
            &truth);
        const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        std::printf("BASELINE thesis-adam-cmsle epochs=%d seconds=%.1f rel_rmse=%.5f best_every_100=%.5f\n",
                    baseline_epochs, s, height_rel_rmse(h, truth), best);
    }
    const int direct_iters = args.count("direct_iters") ? std::stoi(args["direct_iters"]) : 0;
    if (direct_iters > 0) {
        // L-BFGS on the heights from flat with the amplitude loss on all observations (the
        // issue's stepping stone, without the field stages).
        std::vector<double> h(truth.values().size(), 0.0);
        const Loss amplitude{LossKind::Amplitude, 1.0};
        LbfgsOptions lo;
        lo.max_iterations = direct_iters;
        lo.history = 20;
        lo.gradient_tolerance = 0.0;
        const auto t0 = std::chrono::steady_clock::now();
        lbfgs_minimize(
            [&](const std::vector<double>& x, std::vector<double>& g) {
                return observation_loss(truth.with_values(x), observations, amplitude, &g);
            },
            h, lo);
        const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        std::printf("BASELINE lbfgs-amplitude-from-flat iterations=%d seconds=%.1f rel_rmse=%.5f\n", direct_iters, s,
                    height_rel_rmse(truth.with_values(h), truth));
    }
    return 0;
} catch (const std::exception& e) {
    std::fprintf(stderr, "recover_study: %s\n", e.what());
    return 1;
}
