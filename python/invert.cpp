// invert(): the inverse renderer with the options of `wavebrdf invert` (invert.h), returning
// the estimate and the per-epoch metrics instead of writing a directory. The set-up (generated
// default truth, noisy start, observations rendered from the truth) follows apps/cmd_invert.cpp
// step for step, so the same options give the same run as the command line.
#include <algorithm>
#include <cmath>
#include <fstream>
#include <memory>

#include "common.h"
#include "observation_arg.h"
#include "wavebrdf/generate.h"
#include "wavebrdf/invert.h"
#include "wavebrdf/io.h"
#include "wavebrdf/spectrum.h"

namespace wavebrdf::python {

using namespace pybind11::literals;

namespace {

struct InversionResult {
    py::object estimate, truth, observations, metrics, final_slices;
    int epochs = 0;
    bool stopped = false;
};

std::vector<std::array<double, 2>> positions_argument(const py::object& positions) {
    std::vector<std::array<double, 2>> out;
    if (py::isinstance<py::str>(positions)) {
        // A JSON file as the CLI's --positions FILE.json: [[x_um, y_um], ...] or {"positions": [...]}.
        py::object json = py::module_::import("json");
        py::object data;
        try {
            py::object file = py::module_::import("builtins").attr("open")(positions);
            data = json.attr("load")(file);
            file.attr("close")();
        } catch (py::error_already_set& e) {
            throw std::runtime_error(positions.cast<std::string>() + ": cannot read positions (" + e.what() + ")");
        }
        if (py::isinstance<py::dict>(data) && data.contains("positions")) data = data["positions"];
        return positions_argument(data);
    }
    std::vector<std::vector<double>> list;
    try {
        list = positions.cast<std::vector<std::vector<double>>>();
    } catch (const py::cast_error&) {
        throw py::value_error("positions = " + std::string(py::repr(positions)) +
                              " is invalid; expected 'fixed', 'random', a list of (x_um, y_um) or a JSON file");
    }
    if (list.empty()) throw py::value_error("positions is an empty list; expected at least one (x_um, y_um)");
    for (const auto& p : list) {
        if (p.size() != 2 || !std::isfinite(p[0]) || !std::isfinite(p[1]))
            throw py::value_error("positions = " + std::string(py::repr(positions)) +
                                  " is invalid; expected finite pairs (x_um, y_um)");
        out.push_back({p[0], p[1]});
    }
    return out;
}

py::dict metrics_dict(const std::vector<EpochMetrics>& history) {
    const auto column = [&](auto field) {
        std::vector<double> v;
        for (const EpochMetrics& m : history) v.push_back(double(field(m)));
        return owning_array(std::move(v), {static_cast<py::ssize_t>(history.size())});
    };
    py::dict d;
    d["epoch"] = column([](const EpochMetrics& m) { return m.epoch; });
    d["loss"] = column([](const EpochMetrics& m) { return m.loss; });
    d["brdf_mse"] = column([](const EpochMetrics& m) { return m.brdf_mse; });
    d["cmsle_1"] = column([](const EpochMetrics& m) { return m.cmsle_1; });
    d["cmsle_0.001"] = column([](const EpochMetrics& m) { return m.cmsle_0_001; });
    d["rgb_mse"] = column([](const EpochMetrics& m) { return m.rgb_mse; });
    d["rgb_gamma_mse"] = column([](const EpochMetrics& m) { return m.rgb_gamma_mse; });
    d["height_mse"] = column([](const EpochMetrics& m) { return m.height_mse; });
    d["seconds"] = column([](const EpochMetrics& m) { return m.seconds; });
    return d;
}

py::dict epoch_dict(const EpochMetrics& m) {
    return py::dict("epoch"_a = m.epoch, "loss"_a = m.loss, "brdf_mse"_a = m.brdf_mse, "cmsle_1"_a = m.cmsle_1,
                    "cmsle_0.001"_a = m.cmsle_0_001, "rgb_mse"_a = m.rgb_mse, "rgb_gamma_mse"_a = m.rgb_gamma_mse,
                    "height_mse"_a = m.height_mse, "seconds"_a = m.seconds);
}

InversionResult invert(const py::object& truth_arg, const py::object& observations_arg, const py::object& size,
                       const py::object& texel_arg, const py::object& vscale_arg, const py::object& x_um,
                       const py::object& y_um, double sigma_p_um, const std::string& model,
                       const py::object& lambda_um, const py::object& spectral, const py::object& light,
                       int resolution, const py::object& init, int epochs, const std::string& optimizer, double lr,
                       double beta1, double beta2, double decay, const py::object& loss, const py::object& positions,
                       std::uint64_t seed, const py::object& callback) {
    // Settings, checked before any work (the CLI's order).
    InversionSettings settings;
    settings.loss = loss_argument(loss);
    if (optimizer == "adam") settings.optimizer = OptimizerKind::Adam;
    else if (optimizer == "lbfgs") settings.optimizer = OptimizerKind::Lbfgs;
    else bad_argument("optimizer", "'" + optimizer + "'", "'adam' or 'lbfgs'");
    settings.adam = AdamOptions{lr, beta1, beta2, settings.adam.epsilon, decay};
    { Adam check(1, settings.adam); }  // the Adam options, with the library's messages
    if (epochs < 0) bad_argument("epochs", std::to_string(epochs), "an epoch count >= 0");
    settings.epochs = epochs;
    settings.seed = seed;
    std::vector<std::array<double, 2>> position_list;
    const bool positions_text = py::isinstance<py::str>(positions);
    if (positions_text && positions.cast<std::string>() == "random") settings.positions = PositionMode::Random;
    else if (!(positions_text && positions.cast<std::string>() == "fixed")) position_list = positions_argument(positions);
    if (!py::isinstance<py::function>(callback) && !callback.is_none())
        throw py::value_error("callback is not callable; expected callback(metrics, estimate) or None");

    // Scale: given, else the truth's when it is a Heightfield, else 1.
    const bool truth_object = py::isinstance<Heightfield>(truth_arg);
    const double texel_um = texel_arg.is_none()
                                ? (truth_object ? truth_arg.cast<const Heightfield&>().texel_um() : 1.0)
                                : check_positive(texel_arg.cast<double>(), "texel_um");
    const double vscale = vscale_arg.is_none() ? (truth_object ? truth_arg.cast<const Heightfield&>().vscale() : 1.0)
                                               : check_finite(vscale_arg.cast<double>(), "vscale");

    // Wavelengths: the CLI's default is --spectral 8.
    const std::vector<double> lambdas =
        lambda_um.is_none() && spectral.is_none() ? spectral_wavelengths_um(8) : wavelengths(lambda_um, spectral);
    check_resolution(resolution);
    const Model parsed_model = model_from(model);
    const std::array<double, 2> omega_i = light_direction(light);
    check_positive(sigma_p_um, "sigma_p_um");

    // Truth, observations.
    if (!truth_arg.is_none() && !observations_arg.is_none())
        throw py::value_error("truth and observations exclude each other; expected one of them (or neither)");
    std::unique_ptr<Heightfield> truth;
    std::vector<Observation> observations;
    std::array<int, 2> rc = size_argument(size);
    if (!observations_arg.is_none()) {
        observations = py::isinstance<py::str>(observations_arg)
                           ? read_observations_json(observations_arg.cast<std::string>())
                           : observations_argument(observations_arg);
        if (settings.positions == PositionMode::Random && observations.size() < 2)
            throw py::value_error("positions = 'random' with observations needs at least two observations");
        if (py::isinstance<Heightfield>(init) || py::isinstance<py::array>(init)) {
            const py::array shape = py::module_::import("numpy").attr("shape")(init);
            rc = {py::cast<int>(shape[py::int_(0)]), py::cast<int>(shape[py::int_(1)])};
        }
    } else {
        if (truth_arg.is_none()) {
            // The CLI's built-in default: a generated isotropic surface, heights about ±1 texel.
            truth = std::make_unique<Heightfield>(default_inversion_truth(rc[0], rc[1], texel_um, vscale, seed));
        } else {
            truth = std::make_unique<Heightfield>(
                heightfield_argument(truth_arg, "truth", texel_um, vscale, !texel_arg.is_none() || !vscale_arg.is_none()));
        }
        rc = {truth->rows(), truth->cols()};
        Observation base;
        base.query.model = parsed_model;
        base.query.sigma_p_um = sigma_p_um;
        base.query.omega_i = omega_i;
        base.lambdas_um = lambdas;
        base.resolution = resolution;
        if (position_list.empty())
            position_list.push_back({x_um.is_none() ? 0.5 * truth->period_x_um() : check_finite(x_um.cast<double>(), "x_um"),
                                     y_um.is_none() ? 0.5 * truth->period_y_um() : check_finite(y_um.cast<double>(), "y_um")});
        InterruptibleRelease release;
        observations = observe(*truth, base, position_list, settings.render);
    }

    // Initial guess.
    const std::size_t count = static_cast<std::size_t>(rc[0]) * rc[1];
    std::vector<double> start(count, 0.0);
    const bool init_text = py::isinstance<py::str>(init);
    const std::string init_spec = init_text ? init.cast<std::string>() : std::string();
    if (init_text && init_spec == "flat") {
    } else if (init_text && init_spec.rfind("noisy:", 0) == 0) {
        if (!truth) throw py::value_error("init = '" + init_spec + "' needs a truth (noise is added to the truth)");
        double frac = 0.0;
        try {
            std::size_t used = 0;
            frac = std::stod(init_spec.substr(6), &used);
            if (used != init_spec.size() - 6) throw std::invalid_argument(init_spec);
        } catch (const std::logic_error&) {
            bad_argument("init", "'" + init_spec + "'", "'flat', 'noisy:FRAC', a Heightfield, an array or an EXR path");
        }
        if (!(frac >= 0.0) || !std::isfinite(frac)) bad_argument("init", "'" + init_spec + "'", "a noise fraction >= 0");
        start = noisy_start(*truth, frac, seed);  // as the CLI
    } else {
        const Heightfield given = heightfield_argument(init, "init", texel_um, vscale, false);
        if (given.rows() != rc[0] || given.cols() != rc[1])
            throw py::value_error("init is " + std::to_string(given.rows()) + "x" + std::to_string(given.cols()) +
                                  "; expected " + std::to_string(rc[0]) + "x" + std::to_string(rc[1]));
        start = given.values();
    }

    Inversion inversion(observations, Heightfield(rc[0], rc[1], start, texel_um, vscale), settings, truth.get());

    // Run without the GIL; each epoch takes it back to call `callback` and to notice Ctrl-C.
    std::vector<std::vector<double>> last_slices;
    ReleasedCallback python_callback(callback);
    {
        InterruptibleRelease release;
        inversion.run([&](const EpochMetrics& metrics, const Heightfield& estimate, const std::vector<double>&,
                          const std::vector<std::vector<double>>& slices) {
            last_slices = slices;
            return python_callback.step([&](const py::object& f) {
                return f(epoch_dict(metrics),
                         owning_array(std::vector<double>(estimate.values()), {estimate.rows(), estimate.cols()}));
            });
        });
    }
    python_callback.rethrow_if_failed();

    InversionResult result;
    result.estimate = py::cast(inversion.estimate());
    result.truth = truth ? py::cast(*truth) : py::none();
    result.observations = py::cast(observations);
    result.metrics = metrics_dict(inversion.history());
    py::list finals;
    for (std::size_t i = 0; i < last_slices.size() && i < observations.size(); ++i)
        finals.append(observation_array(std::move(last_slices[i]), observations[i]));
    result.final_slices = finals;
    result.epochs = inversion.epoch();
    result.stopped = python_callback.stopped();
    return result;
}

}  // namespace

void bind_invert(py::module_& m) {
    py::class_<InversionResult>(m, "InversionResult", "What invert() returns.")
        .def_readonly("estimate", &InversionResult::estimate, "the recovered Heightfield")
        .def_readonly("truth", &InversionResult::truth, "the truth Heightfield (None with observations)")
        .def_readonly("observations", &InversionResult::observations, "the Observations fitted")
        .def_readonly("metrics", &InversionResult::metrics, R"doc(
dict of float64 arrays, one entry per evaluated epoch (the CLI's metrics.csv columns): epoch,
loss, brdf_mse, cmsle_1, cmsle_0.001, rgb_mse, rgb_gamma_mse, height_mse (um^2 after removing
the mean; NaN without a truth), seconds.
)doc")
        .def_readonly("final_slices", &InversionResult::final_slices,
                      "the observations' slices rendered from the estimate, shaped like their references")
        .def_readonly("epochs", &InversionResult::epochs, "the last epoch reached")
        .def_readonly("stopped", &InversionResult::stopped, "True when the callback stopped the run early");

    m.def("invert", &invert, "truth"_a = py::none(), "observations"_a = py::none(), py::kw_only(), "size"_a = 16,
          "texel_um"_a = py::none(), "vscale"_a = py::none(), "x_um"_a = py::none(), "y_um"_a = py::none(),
          "sigma_p_um"_a = 4.0, "model"_a = "OHS", "lambda_um"_a = py::none(), "spectral"_a = py::none(),
          "light"_a = py::make_tuple(0.0, 0.0), "resolution"_a = 32, "init"_a = "flat", "epochs"_a = 300,
          "optimizer"_a = "adam", "lr"_a = 0.01, "beta1"_a = 0.9, "beta2"_a = 0.99, "decay"_a = 0.005,
          "loss"_a = "cmsle:1", "positions"_a = "fixed", "seed"_a = 1, "callback"_a = py::none(), R"doc(
The inverse renderer (``wavebrdf invert`` without its output directory): recovers heights
whose slices match references. Defaults are the thesis's first experiment (a generated 16x16
truth, normal incidence, 32x32 spectral slice, flat start, Adam 0.01/0.9/0.99 with decay
0.005, 300 epochs, CMSLE epsilon 1). Returns an InversionResult.

truth         Heightfield, 2-D array (texel units) or EXR path; references are rendered from
              it. Default: generated isotropic surface of `size` (rms 0.35 texel, correlation
              2 texels, `seed`). Excludes `observations`.
observations  Observation, list of them, or a JSON path (the CLI's --observations)
size          N or (rows, cols), 1...16384: the generated truth, or the estimate with observations
texel_um      texel width in um (> 0), vscale: vertical scale; default the truth
              Heightfield's, else 1. Given, they apply to the truth and the estimate.
x_um, y_um    footprint centre in um, any finite value, periodic (default: tile centre);
              sigma_p_um 1e-6 to 1e6 and <= 10 tile periods (default 4)
model         'OHS', 'GHS', 'ROHS', 'RGHS' or 'Kirchhoff'
lambda_um     one wavelength in um, or spectral: N (1...256) or a list in um; default spectral 8
light         projected light direction (wx, wy), wx^2 + wy^2 < 1; resolution: slice size n
init          'flat', 'noisy:FRAC' (truth + uniform noise of width FRAC x its height range),
              a Heightfield, a 2-D array or an EXR path
epochs        0 to 10^7 (Adam steps or L-BFGS iterations); optimizer 'adam' or 'lbfgs'
lr, beta1, beta2, decay   Adam's options (lr > 0, betas in [0, 1), decay >= 0 per epoch)
loss          'cmsle:EPS', 'mse', 'amplitude', 'poisson:N' or a Loss
positions     'fixed', 'random' (a new footprint position per epoch, Adam only), a list of
              (x_um, y_um), or a JSON path ([[x_um, y_um], ...])
seed          generated truth, noise and random positions
callback      callback(metrics: dict, estimate: (rows, cols) float64 heights in texel units)
              after each evaluated epoch (epoch 0 included); return False to stop early.
The run releases the GIL; Ctrl-C stops it at the end of an epoch (KeyboardInterrupt).
)doc");
}

}  // namespace wavebrdf::python
