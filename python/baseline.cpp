// The thesis's method as a baseline (baseline.h): recover_heights_thesis.

#include "common.h"
#include "recovery_args.h"
#include "wavebrdf/baseline.h"
#include "wavebrdf/optim.h"

namespace wavebrdf::python {

using namespace pybind11::literals;

void bind_baseline(py::module_& m) {
    const BaselineSettings bs;
    m.def(
        "recover_heights_thesis",
        [](const py::object& observations, const py::object& size, double texel_um, double vscale,
           const py::object& truth, int epochs, double lr, double beta1, double beta2, double decay,
           const py::object& loss, std::uint64_t seed, int report_every, const py::object& callback) {
            const HeightsArguments given = heights_arguments(observations, size, texel_um, vscale);
            BaselineSettings s;
            if (epochs < 0) bad_argument("epochs", std::to_string(epochs), "an epoch count >= 0");
            s.epochs = epochs;
            s.adam = AdamOptions{lr, beta1, beta2, s.adam.epsilon, decay};
            { Adam check(1, s.adam); }  // the Adam options, with the library's messages
            s.loss = loss_argument(loss);
            s.seed = seed;
            if (report_every < 1) bad_argument("report_every", std::to_string(report_every), "a number of epochs >= 1");
            s.report_every = report_every;
            const std::optional<Heightfield> t = optional_truth(truth);
            check_callback(callback);
            std::vector<StageMetrics> history;
            bool stopped = false;
            return run_released(callback, history, stopped, [&](const auto& on_step) {
                return recover_heights_thesis(given.observations, given.rows, given.cols, texel_um, vscale, s, on_step,
                                              t ? &*t : nullptr);
            });
        },
        "observations"_a, "size"_a, "texel_um"_a, "vscale"_a = 1.0, py::kw_only(), "truth"_a = py::none(),
        "epochs"_a = bs.epochs, "lr"_a = bs.adam.lr, "beta1"_a = bs.adam.beta1, "beta2"_a = bs.adam.beta2,
        "decay"_a = bs.adam.decay, "loss"_a = to_string(bs.loss), "seed"_a = bs.seed,
        "report_every"_a = bs.report_every, "callback"_a = py::none(),
        (std::string(R"doc(
The thesis's method as a baseline (baseline.h): Adam on `loss` (default cmsle:1), one
observation drawn at random (from `seed`) per epoch, from a flat start. Returns a Heightfield.
epochs >= 0; lr > 0, beta1 and beta2 in [0, 1), decay >= 0 per epoch (the thesis's 0.01, 0.9,
0.99, 0.005); the callback sees stage 'thesis' every report_every (>= 1) epochs and the last.
)doc") + kSettingsDoc)
            .c_str());
}

}  // namespace wavebrdf::python
