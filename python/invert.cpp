// invert(): the inverse renderer with the options of `wavebrdf invert`, returning the estimate
// and the per-epoch metrics instead of writing a directory. A converter: Python's arguments
// become InversionOptions (inversion_run.h) and the library's prepare_inversion / InversionRun
// run them, the same code as the command line, so the same options give the same run.
#include <cmath>
#include <memory>
#include <optional>

#include "common.h"
#include "observation_arg.h"
#include "progress.h"
#include "wavebrdf/inversion_run.h"
#include "wavebrdf/render_options.h"

namespace wavebrdf::python {

using namespace pybind11::literals;

namespace {

struct InversionResult {
    py::object estimate, truth, observations, metrics, final_slices;
    int epochs = 0;
    bool stopped = false;
};

// A list of (x_um, y_um) pairs (a positions file is the library's: parse_positions_spec).
std::vector<std::array<double, 2>> positions_argument(const py::object& positions) {
    std::vector<std::array<double, 2>> out;
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
                       const py::object& y_um, double sigma_p_um, const std::string& model, const py::object& lambda_um,
                       const py::object& spectral, const py::object& light, int resolution, const py::object& init,
                       int epochs, const std::string& optimizer, double lr, double beta1, double beta2, double decay,
                       const py::object& loss, const py::object& positions, std::uint64_t seed,
                       const py::object& callback, double max_memory_gb, const py::object& quiet,
                       const std::string& path, double tolerance, const py::object& comm_arg) {
    const std::shared_ptr<const Communicator> comm = communicator_argument(comm_arg);
    // Python's arguments → the library's options (inversion_run.h); the set-up and the run are
    // the library's, the same code as `wavebrdf invert`.
    InversionOptions options;
    options.names = OptionStyle::Python;
    options.loss = loss_argument(loss);
    options.optimizer = parse_optimizer(optimizer, "optimizer");
    options.adam = AdamOptions{lr, beta1, beta2, options.adam.epsilon, decay};
    options.epochs = epochs;
    options.seed = seed;
    options.path = parse_render_path(path, "path");
    options.tolerance = tolerance;  // checked by prepare_inversion, named tolerance
    if (!std::isfinite(max_memory_gb) || max_memory_gb < 0.0)
        bad_argument("max_memory_gb", format_number(max_memory_gb), "a limit in GB > 0, or 0 for the physical memory");
    options.max_memory_gb = max_memory_gb;
    if (py::isinstance<py::str>(positions)) {
        options.positions = parse_positions_spec(positions.cast<std::string>(), "positions");
    } else {
        options.positions.kind = PositionsKind::List;
        options.positions.positions_um = positions_argument(positions);
    }
    if (!py::isinstance<py::function>(callback) && !callback.is_none())
        throw py::value_error("callback is not callable; expected callback(metrics, estimate) or None");
    check_quiet(quiet);

    // Scale: given, else the truth's when it is a Heightfield, else 1.
    const HeightfieldScale scale = truth_scale(truth_arg, texel_arg, vscale_arg, 1.0);
    options.texel_um = scale.texel_um;
    options.vscale = scale.vscale;

    // Wavelengths (checked here with Python's names); none: the CLI's default, spectral 8.
    if (!lambda_um.is_none() || !spectral.is_none()) {
        const std::vector<double> lambdas = wavelengths(lambda_um, spectral);
        if (!lambda_um.is_none())
            options.lambda_um = lambdas[0];
        else if (py::isinstance<py::int_>(spectral))
            options.spectral = spectral.cast<int>();
        else
            options.wavelengths_um = lambdas;
    }
    options.resolution = check_resolution(resolution);
    options.model = model_from(model);
    options.omega_i = light_direction(light);
    options.sigma_p_um = check_positive(sigma_p_um, "sigma_p_um");
    if (!x_um.is_none()) options.x_um = check_finite(x_um.cast<double>(), "x_um");
    if (!y_um.is_none()) options.y_um = check_finite(y_um.cast<double>(), "y_um");

    // Truth, observations, initial guess: paths for the library to read, or objects.
    if (!truth_arg.is_none() && !observations_arg.is_none())
        throw py::value_error("truth and observations exclude each other; expected one of them (or neither)");
    const std::array<int, 2> rc = size_argument(size);
    options.rows = rc[0];
    options.cols = rc[1];
    std::optional<Heightfield> truth;
    std::optional<std::vector<Observation>> observations;
    if (!observations_arg.is_none()) {
        if (py::isinstance<py::str>(observations_arg))
            options.observations_path = observations_arg.cast<std::string>();
        else
            observations = observations_argument(observations_arg);
    } else if (!truth_arg.is_none()) {
        truth = heightfield_argument(truth_arg, "truth", options.texel_um, options.vscale,
                                     !texel_arg.is_none() || !vscale_arg.is_none());
    }
    std::optional<Heightfield> initial;
    if (py::isinstance<py::str>(init)) {
        options.init = parse_init_spec(init.cast<std::string>(), "init");
    } else {
        options.init.kind = InitKind::Heights;
        initial = heightfield_argument(init, "init", options.texel_um, options.vscale, false);
    }

    // Set-up and run without the GIL; each epoch takes it back to call `callback` and to
    // notice Ctrl-C.
    options.communicator = comm.get();
    std::unique_ptr<InversionRun> run;
    {
        InterruptibleRelease release;
        run = std::make_unique<InversionRun>(
            prepare_inversion(options, std::move(truth), std::move(observations), std::move(initial)));
    }
    std::vector<std::vector<double>> last_slices;
    // Progress (progress.h): epochs 0 ... epochs, closed however the run ends.
    PythonProgress progress("wrap_invert", callback, quiet, py::int_(run->prepared().settings.epochs + 1));
    ReleasedCallback python_callback(progress.callback());
    {
        InterruptibleRelease release;
        run->run([&](const EpochMetrics& metrics, const Heightfield& estimate, const std::vector<double>&,
                     const std::vector<std::vector<double>>& slices) {
            last_slices = slices;
            return python_callback.step([&](const py::object& f) {
                return f(epoch_dict(metrics),
                         owning_array(std::vector<double>(estimate.values()), {estimate.rows(), estimate.cols()}));
            });
        });
    }
    progress.close();
    python_callback.rethrow_if_failed();

    const Inversion& inversion = run->inversion();
    const PreparedInversion& prepared = run->prepared();
    InversionResult result;
    result.estimate = py::cast(inversion.estimate());
    result.truth = prepared.truth ? py::cast(*prepared.truth) : py::none();
    result.observations = py::cast(prepared.observations);
    result.metrics = metrics_dict(inversion.history());
    py::list finals;
    for (std::size_t i = 0; i < last_slices.size() && i < prepared.observations.size(); ++i)
        finals.append(observation_array(std::move(last_slices[i]), prepared.observations[i]));
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
          "loss"_a = "cmsle:1", "positions"_a = "fixed", "seed"_a = 1, "callback"_a = py::none(),
          "max_memory_gb"_a = 0.0, "quiet"_a = py::none(), "path"_a = "auto", "tolerance"_a = 1e-6,
          "comm"_a = py::none(),
          R"doc(
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
max_memory_gb refuse (MemoryError, before the references are rendered) a run whose
              estimated peak memory exceeds this many GB; 0 (default): the physical memory.
quiet         progress (a tqdm bar if tqdm is installed, else a line on stderr): None (default)
              shows it when stderr is a terminal or in Jupyter, False always, True never
path          'auto', 'separable', 'fft' or 'direct': the path of every render and gradient
tolerance     separable (GHS-type models) and fft paths: error bound relative to the slice
              peak, 1e-12 to 1e-2 (default 1e-6)
comm          None, or an mpi4py communicator: the observations are split over its ranks (each
              renders or keeps its share, by footprint position) and the losses and gradients
              summed over them (the same run as one process's up to the order of the sums);
              every rank calls invert() with the same arguments and gets the same estimate and
              metrics, while `observations` and `final_slices` are its own share; a callback's
              False on any rank stops every rank.
The run releases the GIL; Ctrl-C stops it at the end of an epoch (KeyboardInterrupt).
)doc");
}

}  // namespace wavebrdf::python
