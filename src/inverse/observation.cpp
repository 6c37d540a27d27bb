// Observations and the multi-observation loss: each observation's SlicePlan forwards every
// wavelength (keeping each slice's field), the loss is formed, then the plan's adjoint maps the
// loss's gradient back through the spectral mix to every slice.
#include "wavebrdf/observation.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>

#include <unistd.h>

#include "wavebrdf/adjoint.h"
#include "wavebrdf/input_files.h"
#include "wavebrdf/io.h"
#include "wavebrdf/memory.h"
#include "wavebrdf/spectrum.h"
#include "core/exact_sum.h"
#include "core/json_fields.h"
#include "core/text.h"

namespace wavebrdf {

SliceAttributes slice_attributes(const Observation& observation, const Heightfield* heightfield,
                                 const std::string& made_by) {
    SliceAttributes a;
    a.query = observation.query;
    a.lambdas_um = observation.lambdas_um;
    a.resolution = observation.resolution;
    a.channels = observation.channels();
    if (heightfield != nullptr) {
        a.heightfield_rows = heightfield->rows();
        a.heightfield_cols = heightfield->cols();
        a.texel_um = heightfield->texel_um();
        a.vscale = heightfield->vscale();
    }
    a.made_by = made_by;
    return a;
}

std::vector<std::array<double, 2>> footprint_centres(const std::vector<Observation>& observations) {
    std::vector<std::array<double, 2>> centres;
    centres.reserve(observations.size());
    for (const Observation& o : observations) centres.push_back({{o.query.x_um, o.query.y_um}});
    return centres;
}

std::vector<float> to_reference(const std::vector<double>& values) {
    std::vector<float> out(values.size());
    for (std::size_t i = 0; i < values.size(); ++i) out[i] = static_cast<float>(values[i]);
    return out;
}

std::vector<double> to_doubles(const std::vector<float>& values) { return {values.begin(), values.end()}; }

void validate(const Observation& o, std::size_t index) {
    const std::string where = "observation " + std::to_string(index) + ": ";
    try {
        validate(o.query);
        validate_resolution(o.resolution);
        if (o.lambdas_um.empty()) throw std::invalid_argument("no wavelength given");
        for (double l : o.lambdas_um) validate_lambda(l);
    } catch (const std::invalid_argument& e) {
        throw std::invalid_argument(where + e.what());
    } catch (const std::domain_error& e) {
        throw std::domain_error(where + e.what());
    }
    const std::size_t expected = static_cast<std::size_t>(o.resolution) * o.resolution * o.channels();
    if (o.reference.size() != expected)
        throw std::invalid_argument(where + "reference has " + std::to_string(o.reference.size()) +
                                    " values; expected resolution^2 * channels = " + std::to_string(expected));
    const std::size_t pixels = static_cast<std::size_t>(o.resolution) * o.resolution;
    if (!o.weights.empty()) {
        if (o.weights.size() != pixels)
            throw std::invalid_argument(where + "weights has " + std::to_string(o.weights.size()) +
                                        " values; expected one per pixel, resolution^2 = " + std::to_string(pixels));
        bool any = false;
        for (std::size_t p = 0; p < pixels; ++p) {
            if (!(std::isfinite(o.weights[p]) && o.weights[p] >= 0.0f))
                throw std::domain_error(where + "weight of pixel (" + std::to_string(p / std::size_t(o.resolution)) +
                                        ", " + std::to_string(p % std::size_t(o.resolution)) + ") is " +
                                        detail::format_shortest(double(o.weights[p])) +
                                        "; expected a finite weight >= 0");
            any = any || o.weights[p] > 0.0f;
        }
        if (!any) throw std::invalid_argument(where + "every weight is 0; expected at least one pixel of weight > 0");
    }
    for (std::size_t i = 0; i < o.reference.size(); ++i)
        if (!std::isfinite(o.reference[i]) && (o.weights.empty() || o.weights[i / std::size_t(o.channels())] > 0.0f)) {
            const std::size_t c = std::size_t(o.channels()), p = i / c, n = std::size_t(o.resolution);
            throw std::domain_error(where + "reference pixel (" + std::to_string(p / n) + ", " + std::to_string(p % n) +
                                    ") channel " + std::to_string(i % c) + " is not finite (" +
                                    (std::isnan(o.reference[i]) ? "NaN" : "infinite") + "); expected finite values");
        }
}

std::vector<double> render_observation(const Heightfield& hf, const Observation& o, const RenderOptions& options) {
    std::vector<double> rgb = render_rgb<double>(hf, o.query, o.lambdas_um, o.resolution, options);
    if (o.channels() == 3) return rgb;
    std::vector<double> mono(rgb.size() / 3);
    for (std::size_t i = 0; i < mono.size(); ++i) mono[i] = rgb[3 * i];
    return mono;
}

SlicePlan<double>& ObservationPlans::plan(const Heightfield& hf, const Observation& o, const RenderOptions& options) {
    ++m_clock;
    for (Entry& e : m_entries)
        if (e.plan->matches(hf, o.query, o.lambdas_um, o.resolution, o.channels(), options)) {
            e.plan->set_heights(hf);
            e.last_use = m_clock;
            return *e.plan;
        }
    auto plan = std::make_unique<SlicePlan<double>>(hf, o.query, o.lambdas_um, o.resolution, o.channels(), options);
    ++m_built;
    if (m_entries.size() >= m_capacity) {
        auto oldest = std::min_element(m_entries.begin(), m_entries.end(),
                                       [](const Entry& a, const Entry& b) { return a.last_use < b.last_use; });
        m_entries.erase(oldest);
    }
    m_entries.push_back({std::move(plan), m_clock});
    return *m_entries.back().plan;
}

void ObservationPlans::reserve(std::size_t capacity) { m_capacity = std::max(m_capacity, capacity); }

double observation_slice_loss(const Loss& loss, const std::vector<double>& estimate, const Observation& o,
                              std::vector<double>* gradient) {
    return o.weights.empty() ? loss_value(loss, estimate, o.reference, o.channels(), gradient)
                             : weighted_loss_value(loss, estimate, o.reference, o.channels(), o.weights, gradient);
}

double observation_loss(const Heightfield& hf, const std::vector<Observation>& observations, const Loss& loss,
                        std::vector<double>* gradient, const RenderOptions& options,
                        std::vector<std::vector<double>>* rendered, ObservationPlans* plans, const Communicator& comm) {
    const bool sharded = comm.size() > 1;
    const std::size_t cells = hf.values().size();
    // Checks (agreed over the ranks when sharded: a bad observation on one rank fails all).
    std::vector<double> count{static_cast<double>(observations.size())};
    run_agreed(comm, [&] {
        if (!sharded && observations.empty())
            throw std::invalid_argument("no observations given; expected at least one");
        for (std::size_t i = 0; i < observations.size(); ++i) validate(observations[i], i);
        if (gradient && !gradient->empty() && gradient->size() != cells)
            throw std::invalid_argument("gradient has " + std::to_string(gradient->size()) +
                                        " entries; expected rows*cols = " + std::to_string(cells));
    });
    if (sharded) {
        comm.allreduce_sum(count);
        if (count[0] == 0.0) throw std::invalid_argument("no observations given; expected at least one");
    }
    if (gradient && gradient->empty()) gradient->assign(cells, 0.0);
    if (rendered) rendered->assign(observations.size(), {});
    if (plans) plans->reserve(2 * observations.size() + 2);
    // Every rank's observations summed exactly and independently of their order
    // (core/exact_sum.h): each observation's gradient goes in over its box (the texels its
    // adjoint writes), so the loss and the gradient are the same bits for any thread count and
    // any split over ranks (docs/scale.md, "Equality with one process"). The observations run
    // on all threads, each plan serially inside; cached plans are looked up first, in order
    // (the cache is not thread-safe and holds them all), and two observations that share a plan
    // run one after the other.
    std::vector<SlicePlan<double>*> cached(plans ? observations.size() : 0, nullptr);
    bool shared_plan = false;
    if (plans) {
        for (std::size_t i = 0; i < observations.size(); ++i) cached[i] = &plans->plan(hf, observations[i], options);
        std::vector<SlicePlan<double>*> sorted = cached;
        std::sort(sorted.begin(), sorted.end());
        shared_plan = std::adjacent_find(sorted.begin(), sorted.end()) != sorted.end();
    }
    const double scale = 1.0 / count[0];
    detail::ExactParallelSum sum(gradient ? cells : 0);
    sum.set_parallel(!shared_plan);
    std::vector<double> total_gradient;
    const double total = sum.run(
        observations.size(), comm, total_gradient, [&](std::size_t oi, detail::ExactScratch& scratch) {
            const Observation& o = observations[oi];
            // Forward every wavelength (the plan keeps the fields for the backward pass), mixed to
            // RGB by the plan when the observation has several.
            std::unique_ptr<SlicePlan<double>> own;
            if (!plans)
                own = std::make_unique<SlicePlan<double>>(hf, o.query, o.lambdas_um, o.resolution, o.channels(),
                                                          options);
            SlicePlan<double>& plan = plans ? *cached[oi] : *own;
            const std::vector<double>& estimate = plan.forward();
            std::vector<double> d_estimate;
            const double value = scale * observation_slice_loss(loss, estimate, o, gradient ? &d_estimate : nullptr);
            if (gradient) {
                std::vector<int> rows, cols;
                plan.gradient_box(rows, cols);
                plan.adjoint(d_estimate, scratch.vector(), scale);
                scratch.take_box(rows, cols, std::size_t(hf.cols()));
            }
            if (rendered) (*rendered)[oi] = estimate;
            plan.release();  // a cached plan keeps only its height-independent tables between calls
            return value;
        });
    if (gradient)
        for (std::size_t i = 0; i < cells; ++i) (*gradient)[i] += total_gradient[i];
    return total;
}

namespace {

using nlohmann::json;

std::string directory_of(const std::string& path) {
    const auto slash = path.rfind('/');
    return slash == std::string::npos ? std::string() : path.substr(0, slash + 1);
}

template <typename T>
T field(const json& j, const char* name, const std::string& where) {
    if (!j.contains(name)) throw std::runtime_error(where + "missing field '" + name + "'");
    try {
        return j.at(name).get<T>();
    } catch (const json::exception&) {
        throw std::runtime_error(where + "field '" + name + "' has the wrong type");
    }
}

// An observation's "weights": a list of resolution² numbers (row-major) or an EXR file (its R
// channel; relative to the JSON's folder) of resolution × resolution pixels.
std::vector<float> read_weights(const json& value, int resolution, const std::string& dir, const std::string& where) {
    const std::size_t pixels = std::size_t(resolution) * std::size_t(resolution);
    if (value.is_string()) {
        const std::string file = value.get<std::string>();
        const RgbImage image = read_rgb_exr(file.empty() || file[0] == '/' ? file : dir + file);
        if (image.rows != resolution || image.cols != resolution)
            throw std::runtime_error(where + "weights image " + file + " is " + std::to_string(image.rows) + "x" +
                                     std::to_string(image.cols) + "; expected resolution " +
                                     std::to_string(resolution));
        std::vector<float> w(pixels);
        for (std::size_t p = 0; p < pixels; ++p) w[p] = image.data[3 * p];
        return w;
    }
    if (!value.is_array())
        throw std::runtime_error(where +
                                 "field 'weights' has the wrong type; expected a list of numbers or an EXR file");
    if (value.size() != pixels)
        throw std::runtime_error(where + "field 'weights' has " + std::to_string(value.size()) +
                                 " values; expected one per pixel, resolution^2 = " + std::to_string(pixels));
    std::vector<float> w(pixels);
    for (std::size_t p = 0; p < pixels; ++p) {
        if (!value[p].is_number())
            throw std::runtime_error(where + "field 'weights' value " + std::to_string(p) +
                                     " is not a number; expected weights >= 0");
        w[p] = static_cast<float>(value[p].get<double>());
    }
    return w;
}

}  // namespace

std::vector<Observation> read_observations_json(const std::string& path, double max_memory_gb) {
    check_readable_file(path);
    std::ifstream in(path);
    if (!in) throw std::runtime_error(path + ": cannot open the observations file");
    json doc;
    try {
        doc = json::parse(in);
    } catch (const json::exception& e) {
        throw std::runtime_error(path + ": not valid JSON (" + std::string(e.what()) + ")");
    }
    if (!doc.is_object() || !doc.contains("observations") || !doc["observations"].is_array())
        throw std::runtime_error(path + ": expected an object with an array 'observations'");
    // The references' memory from the JSON alone, before any EXR is read: resolution and the
    // channel count are all it takes (entries that are not valid fail in the pass below).
    const MemoryLimit limit = memory_limit(max_memory_gb);
    double reference_bytes = 0.0;
    for (const json& j : doc["observations"]) {
        if (!j.is_object() || !j.contains("resolution") || !j["resolution"].is_number()) continue;
        const double n = std::min(std::fabs(j["resolution"].get<double>()), 8192.0);
        const double channels = j.contains("lambda_um") ? 1.0 : 3.0;
        reference_bytes += n * n * channels * 8.0 +
                           (j.contains("reference") && j["reference"].is_string() ? n * n * 12.0 : 0.0) +
                           (j.contains("weights") ? n * n * 16.0 : 0.0);
    }
    require_memory(reference_bytes, limit,
                   "reading the " + std::to_string(doc["observations"].size()) + " observations of " + path);
    std::vector<Observation> out;
    const std::string dir = directory_of(path);
    std::size_t index = 0;
    for (const json& j : doc["observations"]) {
        const std::string where = path + ": observation " + std::to_string(index) + ": ";
        if (!j.is_object()) throw std::runtime_error(where + "expected an object");
        Observation o;
        o.query.x_um = field<double>(j, "x_um", where);
        o.query.y_um = field<double>(j, "y_um", where);
        o.query.sigma_p_um = field<double>(j, "sigma_p_um", where);
        if (j.contains("light")) {
            const auto light = field<std::vector<double>>(j, "light", where);
            if (light.size() != 2) throw std::runtime_error(where + "field 'light' must have 2 values");
            o.query.omega_i = {light[0], light[1]};
        }
        if (j.contains("model")) o.query.model = parse_model(field<std::string>(j, "model", where));
        const int given = int(j.contains("lambda_um")) + int(j.contains("spectral")) + int(j.contains("lambdas_um"));
        if (given != 1)
            throw std::runtime_error(where + "expected exactly one of 'lambda_um', 'spectral', 'lambdas_um'");
        if (j.contains("lambda_um")) o.lambdas_um = {field<double>(j, "lambda_um", where)};
        if (j.contains("spectral"))
            o.lambdas_um = spectral_wavelengths_um(detail::json_int32(j, "spectral", 1, k_max_spectral_samples, where));
        if (j.contains("lambdas_um")) o.lambdas_um = field<std::vector<double>>(j, "lambdas_um", where);
        o.resolution = detail::json_int32(j, "resolution", 1, 8192, where);
        if (!j.contains("reference")) throw std::runtime_error(where + "missing field 'reference'");
        if (j["reference"].is_string()) {
            const std::string file = j["reference"].get<std::string>();
            const RgbImage image = read_rgb_exr(file.empty() || file[0] == '/' ? file : dir + file);
            if (image.rows != o.resolution || image.cols != o.resolution)
                throw std::runtime_error(where + "reference image is " + std::to_string(image.rows) + "x" +
                                         std::to_string(image.cols) + "; expected resolution " +
                                         std::to_string(o.resolution));
            if (o.channels() == 3) {
                o.reference.assign(image.data.begin(), image.data.end());
            } else {
                o.reference.resize(image.data.size() / 3);
                for (std::size_t i = 0; i < o.reference.size(); ++i) o.reference[i] = image.data[3 * i];
            }
        } else {
            // null is a value JSON cannot hold (NaN, as a dead pixel's): allowed where its weight is 0.
            const json& values = j["reference"];
            if (!values.is_array()) throw std::runtime_error(where + "field 'reference' has the wrong type");
            o.reference.resize(values.size());
            for (std::size_t k = 0; k < values.size(); ++k) {
                if (!values[k].is_number() && !values[k].is_null())
                    throw std::runtime_error(where + "field 'reference' value " + std::to_string(k) +
                                             " is not a number");
                o.reference[k] = values[k].is_null() ? std::numeric_limits<float>::quiet_NaN()
                                                     : static_cast<float>(values[k].get<double>());
            }
        }
        if (j.contains("weights")) o.weights = read_weights(j["weights"], o.resolution, dir, where);
        try {
            validate(o, index);
        } catch (const std::exception& e) {
            throw std::runtime_error(path + ": " + e.what());
        }
        out.push_back(std::move(o));
        ++index;
    }
    if (out.empty()) throw std::runtime_error(path + ": 'observations' is empty; expected at least one");
    return out;
}

void write_observations_json(const std::string& path, const std::vector<Observation>& observations,
                             ReferenceStorage references) {
    namespace fs = std::filesystem;
    // The EXR folder: the JSON's name without its extension, beside it.
    std::string folder;
    fs::path folder_path, fresh;
    if (references == ReferenceStorage::Exr) {
        const fs::path json_path(path);
        folder = json_path.stem().string();
        if (folder.empty() || folder == "." || folder == "..")
            throw std::invalid_argument("observations file '" + path +
                                        "' has no file name to name its reference folder after; expected e.g. "
                                        "observations.json");
        folder_path = json_path.parent_path() / folder;
        // An existing folder is replaced only when it holds nothing but slices of an earlier
        // set: a user's own folder of that name is not ours to delete.
        std::error_code ec;
        if (fs::exists(fs::symlink_status(folder_path, ec))) {
            if (!fs::is_directory(fs::symlink_status(folder_path, ec)))
                throw std::invalid_argument(folder_path.string() +
                                            " exists and is not a folder; expected the slices' "
                                            "folder of " +
                                            path + " to be new or an earlier set's");
            for (const auto& entry : fs::directory_iterator(folder_path, ec)) {
                const std::string name = entry.path().filename().string();
                const std::size_t digits = name.compare(0, 6, "slice_") == 0     ? 6
                                           : name.compare(0, 8, "weights_") == 0 ? 8
                                                                                 : 0;
                const bool slice = digits > 0 && name.size() >= digits + 8 &&
                                   name.compare(name.size() - 4, 4, ".exr") == 0 &&
                                   name.find_first_not_of("0123456789", digits) == name.size() - 4;
                if (!slice || !entry.is_regular_file() || entry.is_symlink())
                    throw std::invalid_argument(folder_path.string() + " holds '" + name +
                                                "', which is not a slice of an observations set; expected the "
                                                "slices' folder of " +
                                                path + " to be new or an earlier set's");
            }
        }
        // The slices go to a fresh folder first: the earlier set stays whole until they are all written.
        fresh = json_path.parent_path() / ("." + folder + ".writing." + std::to_string(::getpid()));
        fs::remove_all(fresh, ec);
        fs::create_directories(fresh);
    }
    json doc;
    doc["observations"] = json::array();
    try {
        for (std::size_t i = 0; i < observations.size(); ++i) {
            const Observation& o = observations[i];
            validate(o, i);  // a short reference would be read past its end
            json j;
            j["x_um"] = o.query.x_um;
            j["y_um"] = o.query.y_um;
            j["sigma_p_um"] = o.query.sigma_p_um;
            j["light"] = {o.query.omega_i[0], o.query.omega_i[1]};
            j["model"] = to_string(o.query.model);
            if (o.lambdas_um.size() == 1)
                j["lambda_um"] = o.lambdas_um[0];
            else
                j["lambdas_um"] = o.lambdas_um;
            j["resolution"] = o.resolution;
            if (references == ReferenceStorage::Exr) {
                char name[32];
                std::snprintf(name, sizeof name, "slice_%04zu.exr", i);
                write_slice_exr((fresh / name).string(), to_image(to_doubles(o.reference), o.resolution, o.channels()),
                                slice_attributes(o, nullptr, "observations"));
                j["reference"] = folder + "/" + name;
            } else {
                j["reference"] = o.reference;
            }
            if (!o.weights.empty()) {
                if (references == ReferenceStorage::Exr) {
                    char name[48];
                    std::snprintf(name, sizeof name, "weights_%04zu.exr", i);
                    write_rgb_exr((fresh / name).string(), to_image(to_doubles(o.weights), o.resolution, 1));
                    j["weights"] = folder + "/" + name;
                } else {
                    j["weights"] = o.weights;
                }
            }
            doc["observations"].push_back(j);
        }
    } catch (...) {
        std::error_code ec;
        if (!fresh.empty()) fs::remove_all(fresh, ec);
        throw;
    }
    if (references == ReferenceStorage::Exr) {
        // The earlier JSON goes first, so that no failure from here on leaves a set that reads
        // but names the wrong slices: a reader then finds no file, never a mixed set.
        std::error_code ec;
        fs::remove(path, ec);
        const fs::path old = folder_path.parent_path() / ("." + folder + ".old." + std::to_string(::getpid()));
        fs::remove_all(old, ec);
        if (fs::exists(folder_path, ec)) fs::rename(folder_path, old);
        fs::rename(fresh, folder_path);
        fs::remove_all(old, ec);
    }
    write_text_atomically(path, doc.dump(1) + "\n");
}

}  // namespace wavebrdf
