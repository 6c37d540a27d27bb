#include "wavebrdf/threads.h"
#include "wavebrdf/inversion_run.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <exception>
#include <functional>
#include <filesystem>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "core/json_fields.h"
#include "wavebrdf/input_digest.h"
#include "wavebrdf/input_files.h"
#include "wavebrdf/io.h"
#include "wavebrdf/memory.h"
#include "wavebrdf/observation_file.h"
#include "wavebrdf/progress.h"
#include "wavebrdf/render_options.h"
#include "wavebrdf/run_directory.h"
#include "wavebrdf/spectrum.h"
#include "wavebrdf/version.h"

namespace wavebrdf {

namespace fs = std::filesystem;

PositionsSpec parse_positions_spec(const std::string& text, const std::string& /*name*/) {
    PositionsSpec spec;
    if (text == "fixed") return spec;
    if (text == "random") {
        spec.kind = PositionsKind::Random;
        return spec;
    }
    spec.kind = PositionsKind::List;
    spec.positions_um = read_positions_json(text);
    spec.path = text;
    return spec;
}

std::string to_string(const PositionsSpec& positions) {
    switch (positions.kind) {
        case PositionsKind::Fixed: return "fixed";
        case PositionsKind::Random: return "random";
        case PositionsKind::List: return positions.path.empty() ? "list" : positions.path;
    }
    return "fixed";
}

InitSpec parse_init_spec(const std::string& text, const std::string& name) {
    InitSpec spec;
    if (text == "flat") return spec;
    if (text.rfind("noisy:", 0) == 0) {
        spec.kind = InitKind::Noisy;
        spec.text = text;
        try {
            std::size_t used = 0;
            spec.noise_fraction = std::stod(text.substr(6), &used);
            if (used != text.size() - 6) throw std::invalid_argument(text);
        } catch (const std::logic_error&) {
            throw std::invalid_argument(name + " '" + text + "' is invalid; expected flat, noisy:FRAC or FILE.exr");
        }
        try {
            validate_noise_fraction(spec.noise_fraction);
        } catch (const std::exception& e) {
            throw std::domain_error(name + " " + text + ": " + e.what());
        }
        return spec;
    }
    spec.kind = InitKind::File;
    spec.path = text;
    return spec;
}

std::string to_string(const InitSpec& init) {
    switch (init.kind) {
        case InitKind::Flat: return "flat";
        case InitKind::Noisy: {
            if (!init.text.empty()) return init.text;
            std::ostringstream out;
            out.precision(17);
            out << "noisy:" << init.noise_fraction;
            return out.str();
        }
        case InitKind::File: return init.path;
        case InitKind::Heights: return "heights";
    }
    return "flat";
}

std::set<int> parse_epoch_list(const std::string& text, const std::string& name) {
    std::set<int> out;
    std::stringstream in(text);
    std::string item;
    while (std::getline(in, item, ',')) {
        try {
            std::size_t used = 0;
            const int e = std::stoi(item, &used);
            if (used != item.size() || e < 0) throw std::invalid_argument(item);
            out.insert(e);
        } catch (const std::logic_error&) {
            throw std::invalid_argument(name + " '" + text + "' is invalid; expected epochs like 0,10,30");
        }
    }
    return out;
}

std::string format_epoch_list(const std::set<int>& epochs) {
    std::string out;
    for (int e : epochs) out += (out.empty() ? "" : ",") + std::to_string(e);
    return out;
}

OptimizerKind parse_optimizer(const std::string& text, const std::string& name) {
    if (text == "adam") return OptimizerKind::Adam;
    if (text == "lbfgs") return OptimizerKind::Lbfgs;
    throw std::invalid_argument(name + " '" + text + "' is unknown; expected adam or lbfgs");
}

const char* to_string(OptimizerKind optimizer) { return optimizer == OptimizerKind::Lbfgs ? "lbfgs" : "adam"; }

void parse_size(const std::string& name, const std::string& text, int& rows, int& cols) {
    const auto x = text.find_first_of("xX");
    try {
        std::size_t used = 0;
        rows = std::stoi(text.substr(0, x), &used);
        if (used != (x == std::string::npos ? text.size() : x)) throw std::invalid_argument(text);
        cols = rows;
        if (x != std::string::npos) {
            cols = std::stoi(text.substr(x + 1), &used);
            if (used != text.size() - x - 1) throw std::invalid_argument(text);
        }
    } catch (const std::logic_error&) {
        throw std::invalid_argument(name + " '" + text + "' is invalid; expected N or NxM (e.g. 512 or 256x384)");
    }
    if (rows < 1 || cols < 1 || rows > 16384 || cols > 16384)
        throw std::invalid_argument(name + " '" + text + "' is out of range; expected 1 to 16384 per side");
}

namespace {

std::string grid(int rows, int cols) { return std::to_string(rows) + "x" + std::to_string(cols); }

// The wavelengths of the options (spectral 8 when none is given).
std::vector<double> option_wavelengths(const InversionOptions& o) {
    const auto name = [&](const char* key) { return option_name(o.names, key); };
    const int given = int(o.lambda_um.has_value()) + int(o.spectral.has_value()) + int(!o.wavelengths_um.empty());
    if (given > 1) {
        if (o.lambda_um && o.spectral)
            throw std::invalid_argument(name("lambda_um") + " and " + name("spectral") + " exclude each other");
        throw std::invalid_argument(name("lambda_um") + ", " + name("spectral") +
                                    " and a list of wavelengths exclude each other");
    }
    if (o.lambda_um) {
        try {
            validate_lambda(*o.lambda_um);
        } catch (const std::exception& e) {
            throw std::domain_error(name("lambda_um") + ": " + std::string(e.what()));
        }
        return {*o.lambda_um};
    }
    if (!o.wavelengths_um.empty()) {
        for (double l : o.wavelengths_um) validate_lambda(l);
        return o.wavelengths_um;
    }
    const int count = o.spectral ? *o.spectral : 8;
    if (count < 1 || count > k_max_spectral_samples)
        throw std::domain_error(name("spectral") + " " + std::to_string(count) + " is out of range; expected 1 to " +
                                std::to_string(k_max_spectral_samples));
    return spectral_wavelengths_um(count);
}

// The one observation of options.reference_path (and its weights), with the options' query.
Observation reference_observation(const InversionOptions& o, const std::vector<double>& lambdas) {
    const auto name = [&](const char* key) { return option_name(o.names, key); };
    const RgbImage image = read_slice_exr(o.reference_path).image;
    if (image.rows != image.cols)
        throw std::invalid_argument(name("reference") + " " + o.reference_path + " is " + grid(image.rows, image.cols) +
                                    "; expected a square n x n slice");
    if (image.rows != o.resolution)
        throw std::invalid_argument(name("reference") + " " + o.reference_path + " is " + grid(image.rows, image.cols) +
                                    " but " + name("resolution") + " is " + std::to_string(o.resolution) +
                                    "; expected them equal");
    Observation r;
    r.query.x_um = o.x_um ? *o.x_um : 0.0;  // none: set to the tile centre once the size is known
    r.query.y_um = o.y_um ? *o.y_um : 0.0;
    r.query.sigma_p_um = o.sigma_p_um;
    r.query.omega_i = o.omega_i;
    r.query.model = o.model;
    r.lambdas_um = lambdas;
    r.resolution = o.resolution;
    const std::size_t pixels = std::size_t(image.rows) * std::size_t(image.cols);
    const std::size_t c = std::size_t(r.channels());
    r.reference.resize(pixels * c);
    for (std::size_t p = 0; p < pixels; ++p)
        for (std::size_t k = 0; k < c; ++k) r.reference[p * c + k] = image.data[3 * p + k];
    if (!o.weights_path.empty()) {
        const RgbImage w = read_rgb_exr(o.weights_path);
        if (w.rows != image.rows || w.cols != image.cols)
            throw std::invalid_argument(name("weights") + " " + o.weights_path + " is " + grid(w.rows, w.cols) +
                                        "; expected the reference's " + grid(image.rows, image.cols));
        r.weights.resize(pixels);
        for (std::size_t p = 0; p < pixels; ++p) r.weights[p] = w.data[3 * p];
    }
    try {
        validate(r);
    } catch (const std::exception& e) {
        std::string what = e.what();
        const std::string prefix = "observation 0: ";
        if (what.compare(0, prefix.size(), prefix) == 0) what = what.substr(prefix.size());
        throw std::invalid_argument(name("reference") + " " + o.reference_path + ": " + what);
    }
    return r;
}

// What shapes an inversion's run on every rank, for agree_on_inputs: the options that change
// its arithmetic or its collective calls (not the output paths, the memory limit or the names).
void add_options(InputDigest& d, const InversionOptions& o, const std::vector<double>& lambdas) {
    const double none = std::numeric_limits<double>::quiet_NaN();
    d.add(std::vector<double>{double(o.rows), double(o.cols), o.texel_um, o.vscale, o.x_um.value_or(none),
                              o.y_um.value_or(none), o.sigma_p_um, double(int(o.model)), o.omega_i[0], o.omega_i[1],
                              double(o.resolution), double(o.epochs), double(int(o.optimizer)), o.adam.lr,
                              o.adam.beta1, o.adam.beta2, o.adam.epsilon, o.adam.decay, double(int(o.loss.kind)),
                              o.loss.epsilon, o.loss.photons, double(int(o.positions.kind)), double(int(o.init.kind)),
                              o.init.noise_fraction, double(int(o.path)), o.tolerance, double(o.checkpoint_every)});
    d.add(static_cast<long long>(o.seed));
    d.add(lambdas);
    std::vector<double> positions;
    for (const auto& p : o.positions.positions_um) positions.insert(positions.end(), {p[0], p[1]});
    d.add(positions);
    d.add(std::vector<double>(o.snapshots.begin(), o.snapshots.end()));
}

void add_observation(InputDigest& d, const Query& q, const std::vector<double>& lambdas, int resolution) {
    d.add(std::vector<double>{q.x_um, q.y_um, q.sigma_p_um, q.omega_i[0], q.omega_i[1], double(int(q.model)),
                              double(resolution)});
    d.add(lambdas);
}

// prepare_inversion on one rank (no collective calls). `digest` gets what every rank must agree
// on: the options and the whole inputs (every observation, before this rank keeps its share).
PreparedInversion prepare_on_rank(const InversionOptions& o, std::optional<Heightfield> truth,
                                  std::optional<std::vector<Observation>> observations,
                                  std::optional<Heightfield> initial, InputDigest& digest) {
    const Communicator& comm = o.communicator ? *o.communicator : serial_communicator();
    const bool sharded = comm.size() > 1;
    const auto name = [&](const char* key) { return option_name(o.names, key); };
    const MemoryLimit memory = memory_limit(o.max_memory_gb);
    const std::string hint = o.names == OptionStyle::Cli ? "--max-memory-gb" : "max_memory_gb=";

    // Settings, checked before any work.
    PreparedInversion p;
    p.shard.communicator = o.communicator;
    InversionSettings& settings = p.settings;
    settings.loss = o.loss;
    settings.optimizer = o.optimizer;
    settings.adam = o.adam;
    validate_iterations(o.epochs, name("epochs"));
    settings.epochs = o.epochs;
    settings.seed = o.seed;
    if (o.positions.kind == PositionsKind::Random) settings.positions = PositionMode::Random;
    if (o.positions.kind == PositionsKind::List && o.positions.positions_um.empty())
        throw std::invalid_argument(name("positions") + " is an empty list; expected at least one (x_um, y_um)");
    if (o.checkpoint_every < 1)
        throw std::invalid_argument(name("checkpoint_every") + " " + std::to_string(o.checkpoint_every) +
                                    " is invalid; expected >= 1");
    validate(settings);  // the Adam options with their own messages, bounds, L-BFGS vs random positions
    validate_render_tolerance(o.tolerance, name("tolerance"));
    settings.render.path = o.path;
    settings.render.tolerance = o.tolerance;
    validate(settings.render, o.model);  // a path the model has not (or not yet): before any work
    const bool given_reference = !o.reference_path.empty();
    const bool given_observations = observations.has_value() || !o.observations_path.empty() || given_reference;
    if (given_reference && (observations.has_value() || !o.observations_path.empty()))
        throw std::invalid_argument(name("reference") + " and " + name("observations") + " exclude each other");
    if (!o.weights_path.empty() && !given_reference)
        throw std::invalid_argument(name("weights") + " " + o.weights_path + " needs " + name("reference") +
                                    " (an observations file holds its own weights)");
    const bool given_truth = truth.has_value() || !o.truth_path.empty();
    if (o.init.kind == InitKind::Noisy) {
        if (given_observations)
            throw std::invalid_argument(name("init") + " noisy:FRAC needs " + name("truth") +
                                        " (noise is added to the truth)");
        try {
            validate_noise_fraction(o.init.noise_fraction);
        } catch (const std::exception& e) {
            throw std::domain_error(name("init") + " " + to_string(o.init) + ": " + e.what());
        }
    }
    if (o.init.kind == InitKind::Heights && !initial)
        throw std::invalid_argument(name("init") +
                                    " is given as heights but none were passed; expected the initial heights");
    const std::vector<double> lambdas = option_wavelengths(o);
    validate_resolution(o.resolution);
    add_options(digest, o, lambdas);

    // Truth, observations.
    if (given_truth && given_observations)
        throw std::invalid_argument(name("truth") + " and " + name(given_reference ? "reference" : "observations") +
                                    " exclude each other");
    int rows = 0, cols = 0;
    if (given_observations) {
        // An HDF5 file under MPI: this rank reads only its share's slices (the same
        // observation_share of the file's positions as below).
        const bool read_share = !observations && !given_reference && sharded && is_hdf5_file(o.observations_path);
        if (given_reference) {
            p.observations.push_back(reference_observation(o, lambdas));
        } else if (read_share) {
            const ObservationIndex index = read_observation_index(o.observations_path, o.max_memory_gb);
            p.shard.count = index.size();
            for (std::size_t i = 0; i < index.size(); ++i)
                add_observation(digest, index.queries[i], index.lambdas_um[i], index.resolution);
            p.observations = read_observations_file(o.observations_path, comm.rank(), comm.size(), o.max_memory_gb,
                                                    &p.shard.indices);
        } else {
            p.observations = observations ? std::move(*observations)
                                          : read_observations_file(o.observations_path, 0, 1, o.max_memory_gb);
        }
        if (!read_share)
            for (const Observation& r : p.observations) {
                add_observation(digest, r.query, r.lambdas_um, r.resolution);
                digest.add_bytes(r.reference.data(), r.reference.size() * sizeof(float));
                digest.add_bytes(r.weights.data(), r.weights.size() * sizeof(float));
            }
        const std::size_t total = read_share ? p.shard.count : p.observations.size();
        if (total == 0)
            throw std::invalid_argument(name("observations") + " is empty; expected at least one observation");
        rows = initial && o.init.kind == InitKind::Heights ? initial->rows() : o.rows;
        cols = initial && o.init.kind == InitKind::Heights ? initial->cols() : o.cols;
        if (given_reference) {  // no position given: the estimate's tile centre
            Observation& r = p.observations.front();
            if (!o.x_um) r.query.x_um = 0.5 * rows * o.texel_um;
            if (!o.y_um) r.query.y_um = 0.5 * cols * o.texel_um;
        }
        if (settings.positions == PositionMode::Random && total < 2)
            throw std::invalid_argument(name("positions") + " random with " + name("observations") +
                                        " needs at least two observations");
        if (sharded && !read_share) {  // read whole (JSON), this rank's share kept
            p.shard.count = p.observations.size();
            p.shard.indices = observation_share(footprint_centres(p.observations), comm.rank(), comm.size());
            std::vector<Observation> mine;
            for (std::size_t i : p.shard.indices) mine.push_back(std::move(p.observations[i]));
            p.observations = std::move(mine);
        }
    } else {
        if (truth)
            p.truth = std::move(*truth);
        else if (!o.truth_path.empty())
            p.truth = read_heightfield_exr(o.truth_path, o.texel_um, o.vscale);
        // The built-in default: a generated isotropic surface (heights about ±1 texel, like
        // the thesis's crop of the release's isotropic.exr).
        else
            p.truth = default_inversion_truth(o.rows, o.cols, o.texel_um, o.vscale, o.seed);
        rows = p.truth->rows();
        cols = p.truth->cols();
        digest.add(std::vector<double>{double(rows), double(cols), p.truth->texel_um(), p.truth->vscale()});
        digest.add(p.truth->values());
        Observation base;
        base.query.model = o.model;
        base.query.sigma_p_um = o.sigma_p_um;
        base.query.omega_i = o.omega_i;
        base.lambdas_um = lambdas;
        base.resolution = o.resolution;
        std::vector<std::array<double, 2>> positions;
        if (o.positions.kind == PositionsKind::List)
            positions = o.positions.positions_um;
        else
            positions.push_back(
                {o.x_um ? *o.x_um : 0.5 * p.truth->period_x_um(), o.y_um ? *o.y_um : 0.5 * p.truth->period_y_um()});
        if (sharded) {  // this rank renders and holds its share only
            p.shard.count = positions.size();
            p.shard.indices = observation_share(positions, comm.rank(), comm.size());
            std::vector<std::array<double, 2>> mine;
            for (std::size_t i : p.shard.indices) mine.push_back(positions[i]);
            positions = std::move(mine);
        }
        // Before the references are rendered: the whole inversion's estimate against the limit.
        std::vector<Observation> planned(positions.size(), base);
        for (std::size_t i = 0; i < planned.size(); ++i) {
            planned[i].query.x_um = positions[i][0];
            planned[i].query.y_um = positions[i][1];
        }
        require_memory(estimate_inversion_bytes(*p.truth, planned, settings), memory,
                       "invert (" + grid(rows, cols) + " heights, " + std::to_string(planned.size()) +
                           " observation(s) of " + grid(o.resolution, o.resolution) + ")",
                       hint);
        p.observations = observe(*p.truth, base, positions, settings.render);
    }

    // The initial guess.
    std::vector<double> start(static_cast<std::size_t>(rows) * cols, 0.0);
    switch (o.init.kind) {
        case InitKind::Flat: break;
        case InitKind::Noisy: start = noisy_start(*p.truth, o.init.noise_fraction, o.seed); break;
        case InitKind::File:
        case InitKind::Heights: {
            const Heightfield given = o.init.kind == InitKind::File
                                          ? read_heightfield_exr(o.init.path, o.texel_um, o.vscale)
                                          : *initial;
            const std::string what = o.init.kind == InitKind::File ? name("init") + " " + o.init.path : name("init");
            if (given.rows() != rows || given.cols() != cols)
                throw std::invalid_argument(what + " is " + grid(given.rows(), given.cols()) + "; expected " +
                                            grid(rows, cols));
            start = given.values();
            break;
        }
    }
    p.initial = Heightfield(rows, cols, std::move(start), o.texel_um, o.vscale);
    digest.add(p.initial.values());
    if (given_observations)
        require_memory(
            estimate_inversion_bytes(p.initial, p.observations, settings), memory,
            "invert (" + grid(rows, cols) + " heights, " + std::to_string(p.observations.size()) + " observation(s))",
            hint);
    return p;
}

}  // namespace

PreparedInversion prepare_inversion(const InversionOptions& o, std::optional<Heightfield> truth,
                                    std::optional<std::vector<Observation>> observations,
                                    std::optional<Heightfield> initial) {
    PreparedInversion p;
    const Communicator& comm = o.communicator ? *o.communicator : serial_communicator();
    InputDigest digest;
    run_agreed(comm, [&] {
        p = prepare_on_rank(o, std::move(truth), std::move(observations), std::move(initial), digest);
    });
    // Ranks started with different options or files (mpiexec's MPMD form, node-local copies that
    // differ) refuse to run instead of mixing their shares into a wrong estimate.
    agree_on_inputs(comm, digest.value(), "options or inputs");
    return p;
}

InversionRun::InversionRun(PreparedInversion prepared)
    : m_prepared(std::move(prepared)),
      m_inversion(m_prepared.observations, m_prepared.initial, m_prepared.settings,
                  m_prepared.truth ? &*m_prepared.truth : nullptr, m_prepared.shard) {}

InversionStatus InversionRun::run(const Inversion::Callback& on_epoch) {
    bool stopped = false;
    const Communicator& comm = m_inversion.communicator();
    m_inversion.run([&](const EpochMetrics& metrics, const Heightfield& estimate, const std::vector<double>& gradient,
                        const std::vector<std::vector<double>>& slices) {
        // Split over ranks, a stop on any rank stops them all at this epoch.
        const bool stop = on_epoch && !on_epoch(metrics, estimate, gradient, slices);
        if (comm.size() > 1 ? comm.any(stop) : stop) {
            stopped = true;
            return false;
        }
        return true;
    });
    return stopped ? InversionStatus::Stopped : InversionStatus::Completed;
}

// --- run.json ---------------------------------------------------------------------------------

namespace {

// `path` as stored in run.json: absolute, so that --resume finds it from any directory.
std::string absolute_path(const std::string& path) {
    return path.empty() ? path : fs::absolute(path).lexically_normal().string();
}

std::vector<std::vector<double>> wavelength_lists(const std::vector<Observation>& observations) {
    std::vector<std::vector<double>> lists;
    for (const Observation& o : observations) lists.push_back(o.lambdas_um);
    return lists;
}

std::string size_text(int rows, int cols) { return rows == cols ? std::to_string(rows) : grid(rows, cols); }

nlohmann::json to_json(const InversionOptions& o) {
    if (o.positions.kind == PositionsKind::List && o.positions.path.empty())
        throw std::invalid_argument(
            "positions given as values cannot be stored in run.json; expected a positions file");
    if (o.init.kind == InitKind::Heights)
        throw std::invalid_argument(
            "initial heights given as values cannot be stored in run.json; expected an EXR file");
    std::string init = to_string(o.init);
    if (o.init.kind == InitKind::File) init = absolute_path(init);
    std::string positions = to_string(o.positions);
    if (o.positions.kind == PositionsKind::List) positions = absolute_path(positions);
    nlohmann::json j = {{"truth", absolute_path(o.truth_path)},
                        {"observations", absolute_path(o.observations_path)},
                        {"init", init},
                        {"size", size_text(o.rows, o.cols)},
                        {"texel_um", o.texel_um},
                        {"vscale", o.vscale},
                        {"x_um", o.x_um ? nlohmann::json(*o.x_um) : nlohmann::json(nullptr)},
                        {"y_um", o.y_um ? nlohmann::json(*o.y_um) : nlohmann::json(nullptr)},
                        {"sigma_p_um", o.sigma_p_um},
                        {"model", to_string(o.model)},
                        // Not given: null (files written before 0.2 said 0; both read back as not given).
                        {"lambda_um", o.lambda_um ? nlohmann::json(*o.lambda_um) : nlohmann::json(nullptr)},
                        {"spectral", o.spectral ? nlohmann::json(*o.spectral) : nlohmann::json(nullptr)},
                        {"light_x", o.omega_i[0]},
                        {"light_y", o.omega_i[1]},
                        {"resolution", o.resolution},
                        {"epochs", o.epochs},
                        {"optimizer", to_string(o.optimizer)},
                        {"loss", to_string(o.loss)},
                        {"positions", positions},
                        {"lr", o.adam.lr},
                        {"beta1", o.adam.beta1},
                        {"beta2", o.adam.beta2},
                        {"decay", o.adam.decay},
                        {"seed", o.seed},
                        {"snapshots", format_epoch_list(o.snapshots)},
                        {"checkpoint_every", o.checkpoint_every},
                        {"path", to_string(o.path)},
                        {"tolerance", o.tolerance}};
    // Only when used, so that run.json of other runs reads as before.
    if (!o.reference_path.empty()) j["reference"] = absolute_path(o.reference_path);
    if (!o.weights_path.empty()) j["weights"] = absolute_path(o.weights_path);
    if (!o.wavelengths_um.empty()) j["wavelengths_um"] = o.wavelengths_um;
    return j;
}

// Throws nlohmann's exceptions for missing fields and wrong types, std::runtime_error for an
// integer field that is not one (json_fields.h), and the parsers' errors.
InversionOptions from_json(const nlohmann::json& j) {
    InversionOptions o;
    o.truth_path = j.at("truth").get<std::string>();
    o.observations_path = j.at("observations").get<std::string>();
    o.init = parse_init_spec(j.at("init").get<std::string>(), "--init");
    parse_size("--size", j.at("size").get<std::string>(), o.rows, o.cols);
    o.texel_um = j.at("texel_um").get<double>();
    o.vscale = j.at("vscale").get<double>();
    if (!j.at("x_um").is_null()) o.x_um = j.at("x_um").get<double>();
    if (!j.at("y_um").is_null()) o.y_um = j.at("y_um").get<double>();
    o.sigma_p_um = j.at("sigma_p_um").get<double>();
    o.model = parse_model(j.at("model").get<std::string>());
    // Not given: null, or 0 in a run.json written before 0.2.
    if (!j.at("lambda_um").is_null()) {
        const double lambda_um = j.at("lambda_um").get<double>();
        if (lambda_um != 0.0) o.lambda_um = lambda_um;
    }
    // Integers must be integers in range (get<int> would read 8.7 as 8 and wrap 2^40 + 8 to 8).
    if (!j.at("spectral").is_null()) {
        const int spectral = detail::json_int32(j, "spectral", 0, k_max_spectral_samples, "");
        if (spectral != 0) o.spectral = spectral;
    }
    o.omega_i = {j.at("light_x").get<double>(), j.at("light_y").get<double>()};
    o.resolution = detail::json_int32(j, "resolution", 1, 8192, "");
    o.epochs = detail::json_int32(j, "epochs", 0, k_max_iterations, "");
    o.optimizer = parse_optimizer(j.at("optimizer").get<std::string>(), "--optimizer");
    o.loss = parse_loss(j.at("loss").get<std::string>());
    o.positions = parse_positions_spec(j.at("positions").get<std::string>(), "--positions");
    o.adam.lr = j.at("lr").get<double>();
    o.adam.beta1 = j.at("beta1").get<double>();
    o.adam.beta2 = j.at("beta2").get<double>();
    o.adam.decay = j.at("decay").get<double>();
    // Seeds are 64-bit unsigned: the upper half is a JSON unsigned integer, the rest as checked.
    o.seed = j.at("seed").is_number_unsigned() ? j.at("seed").get<std::uint64_t>()
                                               : static_cast<std::uint64_t>(detail::json_int(
                                                     j, "seed", 0, std::numeric_limits<long long>::max(), ""));
    o.snapshots = parse_epoch_list(j.at("snapshots").get<std::string>(), "--snapshots");
    o.checkpoint_every = detail::json_int32(j, "checkpoint_every", 1, std::numeric_limits<int>::max(), "");
    // Absent in an older run.json: the defaults, which those runs used.
    if (j.contains("path")) o.path = parse_render_path(j.at("path").get<std::string>(), "path");
    if (j.contains("tolerance")) {
        o.tolerance = j.at("tolerance").get<double>();
        validate_render_tolerance(o.tolerance, "tolerance");
    }
    if (j.contains("reference")) o.reference_path = j.at("reference").get<std::string>();
    if (j.contains("weights")) o.weights_path = j.at("weights").get<std::string>();
    if (j.contains("wavelengths_um")) {
        if (!j.at("wavelengths_um").is_array() || j.at("wavelengths_um").size() > std::size_t(k_max_spectral_samples))
            throw std::runtime_error("field 'wavelengths_um' is not a list of at most " +
                                     std::to_string(k_max_spectral_samples) + " wavelengths");
        o.wavelengths_um = j.at("wavelengths_um").get<std::vector<double>>();
    }
    return o;
}

// from_json with the errors prefixed by `where` (a file).
InversionOptions options_from_json(const nlohmann::json& args, const std::string& where) {
    try {
        return from_json(args);
    } catch (const nlohmann::json::exception& e) {
        throw std::runtime_error(where + ": corrupt (" + std::string(e.what()) + ")");
    } catch (const std::runtime_error& e) {  // an integer field out of range
        throw std::runtime_error(where + ": " + std::string(e.what()));
    }
}

}  // namespace

std::string inversion_options_to_json(const InversionOptions& options) { return to_json(options).dump(1); }

InversionOptions inversion_options_from_json(const std::string& text, const std::string& where) {
    nlohmann::json j;
    try {
        j = nlohmann::json::parse(text);
    } catch (const nlohmann::json::exception& e) {
        throw std::runtime_error(where + ": corrupt (" + std::string(e.what()) + ")");
    }
    return options_from_json(j, where);
}

std::string metrics_csv(const std::vector<EpochMetrics>& history) {
    std::ostringstream out;
    out.precision(10);
    out << "epoch,loss,brdf_mse,cmsle_1,cmsle_0.001,rgb_mse,rgb_gamma_mse,height_mse,seconds\n";
    for (const EpochMetrics& m : history)
        out << m.epoch << ',' << m.loss << ',' << m.brdf_mse << ',' << m.cmsle_1 << ',' << m.cmsle_0_001 << ','
            << m.rgb_mse << ',' << m.rgb_gamma_mse << ',' << (std::isnan(m.height_mse) ? std::string("nan") : [&] {
                   std::ostringstream s;
                   s.precision(10);
                   s << m.height_mse;
                   return s.str();
               }()) << ',' << m.seconds << '\n';
    return out.str();
}

// --- the run directory --------------------------------------------------------------------------

namespace {

const Communicator& communicator_of(const Communicator* comm) { return comm ? *comm : serial_communicator(); }

// An observation as doubles (query, wavelengths, resolution, reference) and `extra` after it,
// to gather it to rank 0; unpack reverses it.
std::vector<double> pack(const Observation& o, const std::vector<double>& extra) {
    std::vector<double> v{o.query.x_um,
                          o.query.y_um,
                          o.query.sigma_p_um,
                          o.query.omega_i[0],
                          o.query.omega_i[1],
                          double(int(o.query.model)),
                          double(o.resolution),
                          double(o.lambdas_um.size()),
                          double(o.reference.size())};
    v.insert(v.end(), o.lambdas_um.begin(), o.lambdas_um.end());
    v.insert(v.end(), o.reference.begin(), o.reference.end());
    v.insert(v.end(), extra.begin(), extra.end());
    return v;
}

Observation unpack(const std::vector<double>& v, std::vector<double>& extra) {
    Observation o;
    o.query.x_um = v[0];
    o.query.y_um = v[1];
    o.query.sigma_p_um = v[2];
    o.query.omega_i = {v[3], v[4]};
    o.query.model = static_cast<Model>(int(v[5]));
    o.resolution = int(v[6]);
    const std::size_t lambdas = std::size_t(v[7]), reference = std::size_t(v[8]);
    auto at = v.begin() + 9;
    o.lambdas_um.assign(at, at + std::ptrdiff_t(lambdas));
    at += std::ptrdiff_t(lambdas);
    o.reference.assign(at, at + std::ptrdiff_t(reference));
    at += std::ptrdiff_t(reference);
    extra.assign(at, v.end());
    return o;
}

// Calls use(g, observation, extra(observation)) on rank 0 for every observation g of the run in
// global order, `extra` computed by the observation's owner and both gathered from it (one
// observation at a time: rank 0 holds one more, not all). A failure of `use` stops the calls
// but not the gathers; it is rethrown on every rank afterwards (run_agreed).
void for_each_observation_on_root(
    const PreparedInversion& p, const Communicator& comm,
    const std::function<std::vector<double>(const Observation&)>& extra,
    const std::function<void(std::size_t, const Observation&, const std::vector<double>&)>& use) {
    std::exception_ptr failure;
    if (comm.size() == 1) {
        for (std::size_t i = 0; i < p.observations.size(); ++i)
            use(i, p.observations[i], extra ? extra(p.observations[i]) : std::vector<double>());
        return;
    }
    std::size_t next = 0;
    for (std::size_t g = 0; g < p.shard.count; ++g) {
        std::vector<double> local;
        if (next < p.shard.indices.size() && p.shard.indices[next] == g) {
            const Observation& o = p.observations[next++];
            local = pack(o, extra ? extra(o) : std::vector<double>());
        }
        const std::vector<double> all = comm.gather(local);
        if (comm.is_root() && !failure) {
            try {
                std::vector<double> values;
                const Observation o = unpack(all, values);
                use(g, o, values);
            } catch (...) {
                failure = std::current_exception();
            }
        }
    }
    run_agreed(comm, [&] {
        if (failure) std::rethrow_exception(failure);
    });
}

// `write` on rank 0 only, its failure rethrown on every rank (run_agreed).
void on_root(const Communicator& comm, const std::function<void()>& write) {
    std::exception_ptr failure;
    if (comm.is_root()) {
        try {
            write();
        } catch (...) {
            failure = std::current_exception();
        }
    }
    run_agreed(comm, [&] {
        if (failure) std::rethrow_exception(failure);
    });
}

// The epochs of `run` in `dir`: snapshots, checkpoints on options.checkpoint_every and on a
// stop, the final checkpoint, metrics, estimate and renders (rank 0 writes, every rank runs).
InversionDirectoryResult run_epochs(InversionRun& run, const InversionOptions& options, const std::string& dir,
                                    const InversionDirectoryControl& control) {
    Inversion& inversion = run.inversion();
    const Communicator& comm = inversion.communicator();
    const bool root = comm.is_root();
    const std::vector<Observation>& observations = run.prepared().observations;
    const InversionSettings& settings = run.prepared().settings;
    const int rows = inversion.estimate().rows(), cols = inversion.estimate().cols();
    // Rank 0 always holds observation 0 (the first position's block).
    const int channels = observations.empty() ? 1 : observations[0].channels();

    Progress progress("invert", settings.epochs + 1, control.show_progress && root);
    progress.advance(inversion.epoch());
    int last_checkpoint = inversion.epoch();
    auto checkpoint = [&] {
        on_root(comm, [&] {
            inversion.save_checkpoint(dir + "/checkpoint.json");
            write_text_atomically(dir + "/metrics.csv", metrics_csv(inversion.history()));
        });
    };
    const auto on_epoch = [&](const EpochMetrics& m, const Heightfield& estimate, const std::vector<double>& gradient,
                              const std::vector<std::vector<double>>& slices) {
        if (options.snapshots.count(m.epoch)) {
            on_root(comm, [&] {
                char name[64];
                std::snprintf(name, sizeof name, "%04d.npy", m.epoch);
                const std::string base = dir + "/snapshots/";
                write_npy(base + "height_" + name, {std::size_t(rows), std::size_t(cols)}, heights_um(estimate));
                const int n = observations[0].resolution;
                write_npy(base + "slice_" + name, {std::size_t(n), std::size_t(n), std::size_t(channels)}, slices[0]);
                std::vector<double> g = gradient.empty() ? std::vector<double>(estimate.values().size(), 0.0)
                                                         : gradient;
                write_npy(base + "gradient_" + name, {std::size_t(rows), std::size_t(cols)}, g);
            });
        }
        char message[96];
        std::snprintf(message, sizeof message, "epoch %d loss %.4g", m.epoch, m.loss);
        progress.set_message(message);
        progress.advance(1);
        // A stop on any rank stops every rank (the same epoch everywhere).
        const bool stop = comm.any(control.stop && control.stop());
        if (stop) {
            checkpoint();
            return false;
        }
        if (m.epoch - last_checkpoint >= options.checkpoint_every) {
            checkpoint();
            last_checkpoint = m.epoch;
        }
        return true;
    };
    // A failure midway (an exception from the run or from writing its outputs) keeps what was
    // finished: the checkpoint and metrics of the last completed epoch and its estimate, each
    // written on its own so that one failing write does not lose the others.
    InversionDirectoryResult result;
    try {
        result.status = run.run(on_epoch);
    } catch (const std::exception& e) {
        std::vector<std::string> saved;
        const auto keep = [&](const char* what, auto&& write) {
            try {
                write();
                saved.push_back(what);
            } catch (const std::exception&) {}
        };
        if (root) {
            keep("checkpoint.json", [&] { inversion.save_checkpoint(dir + "/checkpoint.json"); });
            keep("metrics.csv", [&] { write_text_atomically(dir + "/metrics.csv", metrics_csv(inversion.history())); });
            keep("estimate.exr", [&] {
                write_heightfield_exr(dir + "/estimate.exr", inversion.estimate(), "wavebrdf invert: estimate");
            });
        }
        std::string list;
        for (const std::string& name : saved) list += (list.empty() ? "" : ", ") + name;
        const auto* agreed = dynamic_cast<const RankFailed*>(&e);
        const std::string message = (agreed ? agreed->message() : std::string(e.what())) +
                                    "; the run stopped at epoch " + std::to_string(inversion.epoch()) + " and " +
                                    (!root           ? "rank 0 keeps what was finished in " + dir
                                     : saved.empty() ? std::string("nothing more could be written to ") + dir
                                                     : "its " + list + " are in " + dir);
        // A failure every rank agreed on stays one (the others are not waiting for this rank);
        // one only this rank saw amid the epochs ends every rank (the others wait for it).
        if (agreed) throw RankFailed(agreed->failed_rank(), message, agreed->cause());
        if (comm.size() > 1) detail::abort_after(comm, message.c_str());
        throw std::runtime_error(message);
    }
    progress.finish();
    checkpoint();

    // Final outputs.
    const Heightfield& estimate = inversion.estimate();
    on_root(comm, [&] {
        write_heightfield_exr(dir + "/estimate.exr", estimate, "wavebrdf invert: estimate");
        write_heightfield_png(dir + "/estimate.png", estimate);
    });
    for_each_observation_on_root(
        run.prepared(), comm, [&](const Observation& o) { return render_observation(estimate, o, settings.render); },
        [&](std::size_t i, const Observation& o, const std::vector<double>& slice) {
            char name[64];
            std::snprintf(name, sizeof name, "/final_%03zu", i);
            const RgbImage image = to_image(slice, o.resolution, channels);
            write_slice_exr(dir + name + ".exr", image,
                            slice_attributes(o, &estimate, "wavebrdf invert: the estimate's slice"));
            write_rgb_png(dir + name + ".png", image, auto_exposure(to_doubles(o.reference)), true);
        });
    result.epoch = inversion.epoch();
    result.history = inversion.history();
    return result;
}

// run.json's "finished": true once every epoch ran and every output was written (rank 0 writes).
void mark_finished(const Communicator& comm, const std::string& dir, nlohmann::json& run_json,
                   const InversionDirectoryResult& result) {
    if (result.status != InversionStatus::Completed) return;
    on_root(comm, [&] {
        run_json["finished"] = true;
        write_text_atomically(dir + "/run.json", run_json.dump(1) + "\n");
    });
}

// The distinct wavelengths of every rank's observations (on rank 0; gathered when sharded).
std::vector<double> all_wavelengths_um(const std::vector<Observation>& observations, const Communicator& comm) {
    std::vector<std::vector<double>> lists = wavelength_lists(observations);
    if (comm.size() > 1) {
        std::vector<double> local;
        for (const auto& list : lists) {
            local.push_back(double(list.size()));
            local.insert(local.end(), list.begin(), list.end());
        }
        const std::vector<double> all = comm.gather(local);
        lists.clear();
        for (std::size_t at = 0; at < all.size();) {
            const std::size_t n = std::size_t(all[at]);
            lists.emplace_back(all.begin() + std::ptrdiff_t(at + 1), all.begin() + std::ptrdiff_t(at + 1 + n));
            at += 1 + n;
        }
    }
    return distinct_wavelengths_um(lists);
}

}  // namespace

InversionDirectoryResult run_inversion_in_directory(const InversionOptions& options, const std::string& dir,
                                                    const InversionDirectoryControl& control) {
    const Communicator& comm = communicator_of(options.communicator);
    nlohmann::json args;
    run_agreed(comm, [&] {
        if (dir.empty()) throw std::invalid_argument("no output directory; expected --out DIR (or --resume DIR)");
        // A new run goes into a new or empty directory (or, with force, one of invert's own runs).
        if (comm.is_root()) check_run_directory(RunKind::Invert, dir, control.force);
        args = to_json(options);  // refuses what run.json cannot hold, before any work
    });
    InversionRun run(prepare_inversion(options));
    const PreparedInversion& p = run.prepared();
    const std::vector<Observation>& observations = p.observations;
    const int rows = p.initial.rows(), cols = p.initial.cols();
    const int channels = observations.empty() ? 1 : observations[0].channels();
    const std::vector<double> wavelengths_um = all_wavelengths_um(observations, comm);
    const std::size_t count = run.inversion().observation_count();

    nlohmann::json run_json;
    on_root(comm, [&] {
        prepare_run_directory(RunKind::Invert, dir, control.force);
        fs::create_directories(dir + "/snapshots");
        check_writable(dir + "/metrics.csv");
        run_json = {
            {"args", args},
            {"title", "wavebrdf invert: " + to_string(options.loss) + ", " + to_string(options.optimizer) + ", " +
                          grid(rows, cols) + " heights, " + std::to_string(options.resolution) + "^2 slices, " +
                          std::to_string(count) + " observation(s), positions " + to_string(options.positions)},
            {"snapshot_epochs", std::vector<int>(options.snapshots.begin(), options.snapshots.end())},
            {"channels", channels},
            {"resolution", observations[0].resolution},
            {"texel_um", options.texel_um},
            {"truth", p.truth.has_value()},
            {"observations", count},
            {"version", k_version},
            {"threads", thread_count()},
            {"wavelengths_um", wavelengths_um},
            // false until every epoch ran and every output is written: a run ended by a signal,
            // a failure or a crash says so (a stop keeps its checkpoint for --resume).
            {"finished", false}};
        write_text_atomically(dir + "/run.json", run_json.dump(1) + "\n");
        const Observation& o = observations[0];
        write_npy(dir + "/reference.npy", {std::size_t(o.resolution), std::size_t(o.resolution), std::size_t(channels)},
                  to_doubles(o.reference));
        if (p.truth) {
            write_npy(dir + "/truth_height.npy", {std::size_t(rows), std::size_t(cols)}, heights_um(*p.truth));
            write_heightfield_exr(dir + "/truth.exr", *p.truth, "wavebrdf invert: truth");
        }
    });
    for_each_observation_on_root(p, comm, {}, [&](std::size_t i, const Observation& o, const std::vector<double>&) {
        char name[64];
        std::snprintf(name, sizeof name, "/reference_%03zu", i);
        const RgbImage image = to_image(to_doubles(o.reference), o.resolution, channels);
        // Rendered from the truth when there is one; given observations have no heightfield.
        const Heightfield* from = p.truth ? &*p.truth : nullptr;
        write_slice_exr(dir + name + ".exr", image, slice_attributes(o, from, "wavebrdf invert: reference"));
        write_rgb_png(dir + name + ".png", image, auto_exposure(to_doubles(o.reference)), true);
    });
    InversionDirectoryResult result = run_epochs(run, options, dir, control);
    mark_finished(comm, dir, run_json, result);
    return result;
}

InversionDirectoryResult resume_inversion_in_directory(const std::string& dir, std::optional<int> epochs,
                                                       double max_memory_gb, const InversionDirectoryControl& control) {
    const Communicator& comm = communicator_of(control.communicator);
    const std::string where = dir + "/run.json";
    nlohmann::json run_json;
    InversionOptions options;
    // Every rank reads run.json (the same file: the errors are the same on every rank).
    run_agreed(comm, [&] {
        check_readable_file(where);
        std::ifstream in(where);
        if (!in)
            throw std::runtime_error(where + ": cannot open; expected a directory written by 'wavebrdf invert --out'");
        try {
            run_json = nlohmann::json::parse(in);
        } catch (const nlohmann::json::exception& e) {
            throw std::runtime_error(where + ": corrupt (" + std::string(e.what()) + ")");
        }
        in.close();
        nlohmann::json args;
        try {
            args = run_json.at("args");
        } catch (const nlohmann::json::exception& e) {
            throw std::runtime_error(where + ": corrupt (" + std::string(e.what()) + ")");
        }
        options = options_from_json(args, where);
        if (!fs::exists(dir + "/checkpoint.json"))
            throw std::runtime_error(dir + "/checkpoint.json: missing; nothing to resume");
    });
    if (epochs) options.epochs = *epochs;
    options.max_memory_gb = max_memory_gb;
    options.communicator = control.communicator;

    InversionRun run(prepare_inversion(options));
    Inversion& inversion = run.inversion();
    run_agreed(comm, [&] {
        if (comm.is_root()) {
            fs::create_directories(dir + "/snapshots");
            check_writable(dir + "/metrics.csv");
        }
        inversion.load_checkpoint(dir + "/checkpoint.json");
        if (options.epochs < inversion.epoch())
            throw std::invalid_argument(option_name(options.names, "epochs") + " " + std::to_string(options.epochs) +
                                        " is below the checkpoint's epoch " + std::to_string(inversion.epoch()) +
                                        "; expected at least that many");
    });
    // The new target, for a later resume, and the run unfinished until it completes again.
    on_root(comm, [&] {
        run_json["args"]["epochs"] = options.epochs;
        run_json["finished"] = false;
        write_text_atomically(where, run_json.dump(1) + "\n");
    });
    InversionDirectoryResult result = run_epochs(run, options, dir, control);
    mark_finished(comm, dir, run_json, result);
    return result;
}

}  // namespace wavebrdf
