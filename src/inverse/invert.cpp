// The inversion loop. Each epoch evaluates the estimate on the observations (metrics, and the
// gradient in fixed mode), reports it, then steps. A checkpoint taken in the report callback
// holds everything the next step needs, and every computation is deterministic for a given
// thread count, so a resumed run continues bit for bit.
#include "wavebrdf/invert.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <random>
#include <stdexcept>
#include <string>

#include "wavebrdf/generate.h"
#include "wavebrdf/input_files.h"
#include "wavebrdf/io.h"
#include "core/json_fields.h"
#include "core/random.h"

namespace wavebrdf {

namespace {

using detail::splitmix64;
using detail::unit_interval;

// FNV-1a over the bytes of the values that define a run.
struct Fingerprint {
    std::uint64_t h = 1469598103934665603ULL;
    void add(const void* data, std::size_t size) {
        const auto* p = static_cast<const unsigned char*>(data);
        for (std::size_t i = 0; i < size; ++i) h = (h ^ p[i]) * 1099511628211ULL;
    }
    void add(double v) { add(&v, sizeof v); }
    void add(std::uint64_t v) { add(&v, sizeof v); }
    void add(int v) { add(&v, sizeof v); }
};

// Everything about an observation that defines a run, reference included.
void add_observation(Fingerprint& f, const Observation& o) {
    f.add(o.query.x_um);
    f.add(o.query.y_um);
    f.add(o.query.sigma_p_um);
    f.add(o.query.omega_i[0]);
    f.add(o.query.omega_i[1]);
    f.add(int(o.query.model));
    f.add(o.resolution);
    for (double l : o.lambdas_um) f.add(l);
    for (const float r : o.reference) f.add(double(r));
    for (const float w : o.weights) f.add(double(w));
}

std::string hex(std::uint64_t h) {
    std::ostringstream out;
    out << std::hex << h;
    return out.str();
}

// `states` chained over every rank's observations in global order (add_observation): serial,
// over `local`; sharded, each observation by its owner, the states broadcast from it.
void chain_observations(std::vector<Fingerprint>& states, const std::vector<Observation>& local,
                        const std::vector<std::size_t>& indices, std::size_t count, const Communicator& comm) {
    if (comm.size() == 1) {
        for (const Observation& o : local)
            for (Fingerprint& f : states) add_observation(f, o);
        return;
    }
    std::vector<double> owner(count, 0.0);
    for (std::size_t index : indices) owner[index] = comm.rank();
    comm.allreduce_sum(owner);  // one rank adds its number to each entry, the others 0: exact
    std::vector<double> bits(states.size());
    std::size_t next = 0;  // this rank's next observation
    for (std::size_t g = 0; g < count; ++g) {
        const int from = static_cast<int>(owner[g]);
        if (from == comm.rank()) {
            for (Fingerprint& f : states) add_observation(f, local[next]);
            ++next;
        }
        for (std::size_t i = 0; i < states.size(); ++i) std::memcpy(&bits[i], &states[i].h, sizeof(double));
        comm.broadcast(bits, from);  // bits, not numbers: a broadcast copies them unchanged
        for (std::size_t i = 0; i < states.size(); ++i) std::memcpy(&states[i].h, &bits[i], sizeof(double));
    }
}

// The values the fingerprint covers, by name, so that a mismatched checkpoint can say which
// of them differ (the observations as a hash of their own, and their count over all ranks).
nlohmann::json run_summary(const Heightfield& estimate, const InversionSettings& s, std::size_t observations,
                           const std::string& observations_hash) {
    return {{"size", std::to_string(estimate.rows()) + "x" + std::to_string(estimate.cols())},
            {"texel_um", estimate.texel_um()},
            {"vscale", estimate.vscale()},
            {"loss", to_string(s.loss)},
            {"optimizer", s.optimizer == OptimizerKind::Adam ? "adam" : "lbfgs"},
            {"lr", s.adam.lr},
            {"beta1", s.adam.beta1},
            {"beta2", s.adam.beta2},
            {"adam_epsilon", s.adam.epsilon},
            {"decay", s.adam.decay},
            {"positions", s.positions == PositionMode::Fixed ? "fixed" : "random"},
            {"seed", s.seed},
            {"observations", observations},
            {"observations_hash", observations_hash}};
}

// "lr 0.01 in the checkpoint, 0.02 now; …" for the entries of `now` that differ in `saved`.
std::string describe_differences(const nlohmann::json& saved, const nlohmann::json& now) {
    const auto text = [](const nlohmann::json& v) { return v.is_string() ? v.get<std::string>() : v.dump(); };
    std::string out;
    for (const auto& [key, value] : now.items()) {
        if (saved.contains(key) && saved[key] == value) continue;
        if (!out.empty()) out += "; ";
        out += key + " " + (saved.contains(key) ? text(saved[key]) : std::string("(absent)")) + " in the checkpoint, " +
               text(value) + " now";
    }
    return out;
}

}  // namespace

Inversion::Inversion(std::vector<Observation> observations, Heightfield initial, InversionSettings settings,
                     const Heightfield* truth, ObservationShard shard)
    : m_observations(std::move(observations)),
      m_estimate(std::move(initial)),
      m_settings(settings),
      m_truth(truth),
      m_adam(m_estimate.values().size(), settings.adam),
      m_comm(shard.communicator ? shard.communicator : &serial_communicator()) {
    const bool sharded = m_comm->size() > 1;
    run_agreed(*m_comm, [&] {
        validate(m_settings);
        if (!sharded && m_observations.empty())
            throw std::invalid_argument("no observations given; expected at least one");
        if (sharded) {
            if (shard.indices.size() != m_observations.size())
                throw std::invalid_argument("the shard lists " + std::to_string(shard.indices.size()) +
                                            " observations but " + std::to_string(m_observations.size()) +
                                            " are given; expected one index per observation");
            for (std::size_t i = 0; i < shard.indices.size(); ++i)
                if (shard.indices[i] >= shard.count || (i > 0 && shard.indices[i] <= shard.indices[i - 1]))
                    throw std::invalid_argument("the shard's observation indices are not ascending below " +
                                                std::to_string(shard.count) + "; expected observation_share's");
        }
        for (std::size_t i = 0; i < m_observations.size(); ++i)
            validate(m_observations[i], sharded ? shard.indices[i] : i);
        validate_iterations(settings.epochs, "epochs");
        for (const Observation& o : m_observations)
            validate_footprint(o.query.sigma_p_um, m_estimate.period_x_um(), m_estimate.period_y_um());
        if (settings.optimizer == OptimizerKind::Lbfgs && settings.positions == PositionMode::Random)
            throw std::invalid_argument(
                "L-BFGS needs a fixed objective; use --positions fixed (or Adam for random positions)");
        if (truth && (truth->rows() != m_estimate.rows() || truth->cols() != m_estimate.cols()))
            throw std::invalid_argument("truth is " + std::to_string(truth->rows()) + "x" +
                                        std::to_string(truth->cols()) + " but the estimate is " +
                                        std::to_string(m_estimate.rows()) + "x" + std::to_string(m_estimate.cols()) +
                                        "; expected the same size");
    });
    if (sharded) {
        m_indices = std::move(shard.indices);
        m_count = shard.count;
        if (m_count == 0) throw std::invalid_argument("no observations given; expected at least one");
    } else {
        m_count = m_observations.size();
        for (std::size_t i = 0; i < m_count; ++i) m_indices.push_back(i);
    }
    // The fingerprint of the run (settings, then every observation in global order) and the
    // observations' own hash, once (collective when sharded).
    Fingerprint f;
    f.add(m_estimate.rows());
    f.add(m_estimate.cols());
    f.add(m_estimate.texel_um());
    f.add(m_estimate.vscale());
    f.add(int(m_settings.loss.kind));
    f.add(m_settings.loss.epsilon);
    f.add(int(m_settings.optimizer));
    f.add(m_settings.adam.lr);
    f.add(m_settings.adam.beta1);
    f.add(m_settings.adam.beta2);
    f.add(m_settings.adam.epsilon);
    f.add(m_settings.adam.decay);
    f.add(int(m_settings.positions));
    f.add(m_settings.seed);
    std::vector<Fingerprint> states{f, Fingerprint{}};
    chain_observations(states, m_observations, m_indices, m_count, *m_comm);
    m_fingerprint = hex(states[0].h);
    m_observations_hash = hex(states[1].h);
}

Heightfield default_inversion_truth(int rows, int cols, double texel_um, double vscale, std::uint64_t seed) {
    SurfaceParams p;
    p.type = SurfaceType::Isotropic;
    p.rows = rows;
    p.cols = cols;
    p.texel_um = texel_um;
    p.rms_height_um = 0.35 * texel_um;
    p.correlation_um = 2.0 * texel_um;
    p.seed = seed;
    return generate_heightfield(p).with_scale(texel_um, vscale);
}

double estimate_inversion_bytes(const Heightfield& heights, const std::vector<Observation>& observations,
                                const InversionSettings& settings) {
    double slices = 0.0, largest_render = 0.0;
    for (const Observation& o : observations) {
        const double n = o.resolution;
        slices += 3.0 * n * n * o.channels() * 8.0;
        largest_render = std::max(largest_render, estimate_render_bytes(heights, o.query, o.resolution, settings.render,
                                                                        8, o.channels() == 3));
    }
    const double texels = double(heights.rows()) * double(heights.cols());
    const double optimiser = settings.optimizer == OptimizerKind::Lbfgs ? 2.0 * settings.lbfgs.history + 6.0 : 6.0;
    return slices + 2.0 * largest_render + texels * 8.0 * optimiser;
}

std::vector<Observation> observe(const Heightfield& truth, const Observation& base,
                                 const std::vector<std::array<double, 2>>& positions_um, const RenderOptions& options) {
    std::vector<Observation> out;
    for (const auto& pos : positions_um) {
        Observation o = base;
        o.query.x_um = pos[0];
        o.query.y_um = pos[1];
        validate(o.query);
        o.reference = to_reference(render_observation(truth, o, options));
        out.push_back(std::move(o));
    }
    return out;
}

void validate_noise_fraction(double frac) {
    if (!(frac >= 0.0 && frac <= kMaxNoiseFraction)) {
        char text[160];
        std::snprintf(text, sizeof text, "noise fraction %g is invalid; expected a fraction from 0 to %g", frac,
                      kMaxNoiseFraction);
        throw std::domain_error(text);
    }
}

void validate(const InversionSettings& settings) {
    { Adam check(0, settings.adam); }  // its own messages
    if (!(settings.adam.lr <= kMaxInversionLr)) {
        char text[200];
        std::snprintf(text, sizeof text, "Adam lr %g is too large; expected at most %g (a step in texel units)",
                      settings.adam.lr, kMaxInversionLr);
        throw std::domain_error(text);
    }
    std::vector<double> x(1, 0.0);
    LbfgsOptions lbfgs = settings.lbfgs;
    lbfgs.max_iterations = 0;
    lbfgs_minimize(
        [](const std::vector<double>&, std::vector<double>& g) {
            g.assign(1, 0.0);
            return 0.0;
        },
        x,
        lbfgs);  // validates the options (no step with 0 iterations)
    if (settings.epochs < 0)
        throw std::invalid_argument("epochs " + std::to_string(settings.epochs) + " is negative; expected >= 0");
    if (settings.optimizer == OptimizerKind::Lbfgs && settings.positions == PositionMode::Random)
        throw std::invalid_argument(
            "L-BFGS needs a fixed objective; use --positions fixed (or Adam for random positions)");
}

std::vector<double> noisy_start(const Heightfield& truth, double frac, std::uint64_t seed) {
    validate_noise_fraction(frac);
    const auto& t = truth.values();
    const auto [lo, hi] = std::minmax_element(t.begin(), t.end());
    const double width = frac * (*hi - *lo);
    std::mt19937_64 rng(seed ^ 0x5eedULL);
    std::vector<double> out(t.size());
    for (std::size_t i = 0; i < t.size(); ++i) out[i] = t[i] + width * (detail::uniform01(rng) - 0.5);
    return out;
}

std::array<double, 2> Inversion::random_position(std::uint64_t seed, int epoch, const Heightfield& tile) {
    const std::uint64_t a = splitmix64(seed * 0x100000001b3ULL + static_cast<std::uint64_t>(epoch));
    const std::uint64_t b = splitmix64(a);
    return {unit_interval(a) * tile.period_x_um(), unit_interval(b) * tile.period_y_um()};
}

std::vector<Observation> Inversion::epoch_observations(int epoch) const {
    if (m_settings.positions == PositionMode::Fixed) return m_observations;
    // Sharded: every rank draws the same; the owner of the drawn observation (of observation 0,
    // the base of a drawn position: rank 0's) evaluates it, the others none.
    if (m_truth) {
        if (m_indices.empty() || m_indices[0] != 0) return {};
        Observation o = m_observations[0];
        const auto pos = random_position(m_settings.seed, epoch, m_estimate);
        o.query.x_um = pos[0];
        o.query.y_um = pos[1];
        o.reference = to_reference(render_observation(*m_truth, o, m_settings.render));
        return {o};
    }
    const std::uint64_t pick = splitmix64(m_settings.seed ^ (0xabcdefULL + static_cast<std::uint64_t>(epoch)));
    const std::size_t global = static_cast<std::size_t>(pick % m_count);
    const auto found = std::lower_bound(m_indices.begin(), m_indices.end(), global);
    if (found == m_indices.end() || *found != global) return {};
    return {m_observations[static_cast<std::size_t>(found - m_indices.begin())]};
}

EpochMetrics Inversion::evaluate(std::vector<double>* gradient, std::vector<std::vector<double>>* rendered) const {
    EpochMetrics m;
    std::vector<std::vector<double>> slices;
    m.loss = observation_loss(m_estimate, m_observations, m_settings.loss, gradient, m_settings.render, &slices,
                              &m_plans, *m_comm);
    const Loss mse{LossKind::MSE, 1.0}, cmsle1{LossKind::CMSLE, 1.0}, cmsle3{LossKind::CMSLE, 1e-3};
    const double scale = 1.0 / double(m_count);
    for (std::size_t i = 0; i < m_observations.size(); ++i) {
        const Observation& o = m_observations[i];
        m.brdf_mse += scale * observation_slice_loss(mse, slices[i], o);
        m.cmsle_1 += scale * observation_slice_loss(cmsle1, slices[i], o);
        m.cmsle_0_001 += scale * observation_slice_loss(cmsle3, slices[i], o);
        if (o.weights.empty()) {
            m.rgb_mse += scale * rgb_mse(slices[i], o.reference, o.channels());
            m.rgb_gamma_mse += scale * rgb_gamma_mse(slices[i], o.reference, o.channels());
        } else {  // over the pixels of weight > 0 (the tone-mapped metrics are not weighted)
            std::vector<double> estimate, reference;
            const std::size_t c = std::size_t(o.channels());
            for (std::size_t p = 0; p < o.weights.size(); ++p)
                if (o.weights[p] > 0.0f)
                    for (std::size_t k = 0; k < c; ++k) {
                        estimate.push_back(slices[i][p * c + k]);
                        reference.push_back(double(o.reference[p * c + k]));
                    }
            m.rgb_mse += scale * rgb_mse(estimate, reference, o.channels());
            m.rgb_gamma_mse += scale * rgb_gamma_mse(estimate, reference, o.channels());
        }
    }
    if (m_comm->size() > 1) {
        std::vector<double> sums{m.brdf_mse, m.cmsle_1, m.cmsle_0_001, m.rgb_mse, m.rgb_gamma_mse};
        m_comm->allreduce_sum(sums);
        m.brdf_mse = sums[0], m.cmsle_1 = sums[1], m.cmsle_0_001 = sums[2], m.rgb_mse = sums[3];
        m.rgb_gamma_mse = sums[4];
    }
    if (m_truth) {
        // In µm², on the heights H = v·w·h of both.
        std::vector<double> est = m_estimate.values(), tru = m_truth->values();
        for (double& v : est) v *= m_estimate.vscale() * m_estimate.texel_um();
        for (double& v : tru) v *= m_truth->vscale() * m_truth->texel_um();
        m.height_mse = height_mse(est, tru);
    }
    if (rendered) *rendered = std::move(slices);
    return m;
}

void Inversion::run(const Callback& on_epoch) {
    const auto start = std::chrono::steady_clock::now();
    auto seconds = [&] {
        return m_seconds_before + std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    };
    const bool fixed = m_settings.positions == PositionMode::Fixed;
    // Report the estimate of the current epoch unless a checkpoint already did.
    auto report = [&](const std::vector<double>& gradient, EpochMetrics& metrics,
                      const std::vector<std::vector<double>>& slices) {
        if (!m_history.empty() && m_history.back().epoch == m_epoch) return true;
        metrics.epoch = m_epoch;
        metrics.seconds = seconds();
        m_history.push_back(metrics);
        return !on_epoch || on_epoch(metrics, m_estimate, gradient, slices);
    };

    if (m_settings.optimizer == OptimizerKind::Adam) {
        while (true) {
            std::vector<double> gradient;
            std::vector<std::vector<double>> slices;
            EpochMetrics metrics = evaluate(fixed ? &gradient : nullptr, &slices);
            if (!fixed)
                observation_loss(m_estimate, epoch_observations(m_epoch), m_settings.loss, &gradient, m_settings.render,
                                 nullptr, &m_plans, *m_comm);
            if (!report(gradient, metrics, slices)) break;
            if (m_epoch >= m_settings.epochs) break;
            std::vector<double> x = m_estimate.values();
            m_adam.step(x, gradient, m_epoch);
            m_estimate = m_estimate.with_values(std::move(x));
            ++m_epoch;
        }
        m_seconds_before = seconds();
        return;
    }

    // L-BFGS: one iteration per epoch. Its curvature history (m_lbfgs) is updated before each
    // report, so a checkpoint taken there continues exactly.
    {
        std::vector<double> gradient;
        std::vector<std::vector<double>> slices;
        EpochMetrics metrics = evaluate(&gradient, &slices);
        if (!report(gradient, metrics, slices) || m_epoch >= m_settings.epochs) {
            m_seconds_before = seconds();
            return;
        }
    }
    std::vector<double> x = m_estimate.values();
    LbfgsOptions options = m_settings.lbfgs;
    options.max_iterations = m_settings.epochs - m_epoch;
    auto objective = [&](const std::vector<double>& v, std::vector<double>& g) {
        g.clear();  // observation_loss adds into its gradient (adjoint.h)
        return observation_loss(m_estimate.with_values(v), m_observations, m_settings.loss, &g, m_settings.render,
                                nullptr, &m_plans, *m_comm);
    };
    bool stopped = false;
    lbfgs_minimize(
        objective, x, options,
        [&](int, double) {
            m_estimate = m_estimate.with_values(x);
            ++m_epoch;
            std::vector<double> gradient;
            std::vector<std::vector<double>> slices;
            EpochMetrics metrics = evaluate(&gradient, &slices);
            if (!report(gradient, metrics, slices)) {
                stopped = true;
                return false;
            }
            return m_epoch < m_settings.epochs;
        },
        &m_lbfgs);
    if (!stopped) m_estimate = m_estimate.with_values(x);
    m_seconds_before = seconds();
}

std::string Inversion::fingerprint() const { return m_fingerprint; }

void Inversion::save_checkpoint(const std::string& path) const {
    nlohmann::json j;
    j["format"] = "wavebrdf-checkpoint-1";
    j["fingerprint"] = fingerprint();
    j["run"] = run_summary(m_estimate, m_settings, m_count, m_observations_hash);
    j["epoch"] = m_epoch;
    j["seconds"] = m_history.empty() ? m_seconds_before : m_history.back().seconds;
    j["rows"] = m_estimate.rows();
    j["cols"] = m_estimate.cols();
    j["heights"] = m_estimate.values();
    j["adam_m"] = m_adam.state().m;
    j["adam_v"] = m_adam.state().v;
    j["adam_steps"] = m_adam.state().steps;
    j["lbfgs_s"] = m_lbfgs.s;
    j["lbfgs_y"] = m_lbfgs.y;
    j["lbfgs_rho"] = m_lbfgs.rho;
    nlohmann::json rows = nlohmann::json::array();
    for (const EpochMetrics& m : m_history)
        rows.push_back({m.epoch, m.loss, m.brdf_mse, m.cmsle_1, m.cmsle_0_001, m.rgb_mse, m.rgb_gamma_mse,
                        std::isnan(m.height_mse) ? nlohmann::json(nullptr) : nlohmann::json(m.height_mse), m.seconds});
    j["metrics"] = rows;
    write_text_atomically(path, j.dump() + "\n");
}

void Inversion::load_checkpoint(const std::string& path) {
    check_readable_file(path);
    std::ifstream in(path);
    if (!in) throw std::runtime_error(path + ": cannot open the checkpoint");
    nlohmann::json j;
    const std::string where = path + ": ";
    // Heights per side: a checkpoint of a heightfield larger than any we make is corrupt.
    constexpr long long k_max_side = 16384;
    try {
        j = nlohmann::json::parse(in);
        if (j.at("format").get<std::string>() != "wavebrdf-checkpoint-1")
            throw std::runtime_error(path + ": unknown checkpoint format");
        if (j.at("fingerprint").get<std::string>() != fingerprint()) {
            const std::string differences = j.contains("run") ? describe_differences(
                                                                    j["run"], run_summary(m_estimate, m_settings,
                                                                                          m_count, m_observations_hash))
                                                              : std::string();
            throw std::runtime_error(path + ": the checkpoint belongs to a different run (" +
                                     (differences.empty() ? "settings, observations or seed differ" : differences) +
                                     "); expected the same options as the run it came from");
        }
        if (detail::json_int(j, "rows", 1, k_max_side, where) != m_estimate.rows() ||
            detail::json_int(j, "cols", 1, k_max_side, where) != m_estimate.cols())
            throw std::runtime_error(path + ": checkpoint size differs from the heightfield");
        Adam::State state;
        state.m = j.at("adam_m").get<std::vector<double>>();
        state.v = j.at("adam_v").get<std::vector<double>>();
        state.steps = detail::json_int(j, "adam_steps", 0, std::numeric_limits<long long>::max(), where);
        m_adam.set_state(state);
        // Absent in checkpoints written before the history was kept: L-BFGS then starts afresh.
        LbfgsState lbfgs;
        if (j.contains("lbfgs_s")) {
            lbfgs.s = j.at("lbfgs_s").get<std::vector<std::vector<double>>>();
            lbfgs.y = j.at("lbfgs_y").get<std::vector<std::vector<double>>>();
            lbfgs.rho = j.at("lbfgs_rho").get<std::vector<double>>();
        }
        validate_lbfgs_state(lbfgs, m_estimate.values().size(), m_settings.lbfgs.history);
        m_lbfgs = std::move(lbfgs);
        m_estimate = m_estimate.with_values(j.at("heights").get<std::vector<double>>());
        m_epoch = detail::json_int32(j, "epoch", 0, k_max_iterations, where);
        m_seconds_before = j.at("seconds").get<double>();
        m_history.clear();
        for (const auto& r : j.at("metrics")) {
            EpochMetrics m;
            m.epoch = static_cast<int>(detail::json_int_value(r.at(0), where + "metrics epoch", 0, k_max_iterations));
            m.loss = r.at(1).get<double>();
            m.brdf_mse = r.at(2).get<double>();
            m.cmsle_1 = r.at(3).get<double>();
            m.cmsle_0_001 = r.at(4).get<double>();
            m.rgb_mse = r.at(5).get<double>();
            m.rgb_gamma_mse = r.at(6).get<double>();
            m.height_mse = r.at(7).is_null() ? std::numeric_limits<double>::quiet_NaN() : r.at(7).get<double>();
            m.seconds = r.at(8).get<double>();
            m_history.push_back(m);
        }
    } catch (const nlohmann::json::exception& e) {
        throw std::runtime_error(path + ": corrupt checkpoint (" + std::string(e.what()) + ")");
    } catch (const std::invalid_argument& e) {
        throw std::runtime_error(path + ": checkpoint does not fit this run (" + std::string(e.what()) + ")");
    }
}

}  // namespace wavebrdf
