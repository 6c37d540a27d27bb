// Error bars of a recovered heightfield (uncertainty.h): height_uncertainty.

#include "common.h"
#include "recovery_args.h"
#include "wavebrdf/uncertainty.h"

namespace wavebrdf::python {

using namespace pybind11::literals;

void bind_uncertainty(py::module_& m) {
    const UncertaintySettings us;
    m.def(
        "height_uncertainty",
        [](const py::object& observations, const Heightfield& estimate, const py::object& loss, int probe_spacing,
           int rounds, double cg_tolerance, int cg_iterations, std::uint64_t seed, int dense_max_texels,
           const py::object& comm_arg) {
            const std::shared_ptr<const Communicator> comm = ranks_argument(comm_arg);
            const std::vector<Observation> list = observations_or_file(observations);
            const Loss l = loss_argument(loss);
            UncertaintySettings s;
            s.probe_spacing = probe_spacing;
            s.rounds = rounds;
            s.cg_tolerance = cg_tolerance;
            s.cg_iterations = cg_iterations;
            s.seed = seed;
            s.dense_max_texels = dense_max_texels;
            HeightUncertainty u;
            {
                py::gil_scoped_release release;
                u = height_uncertainty(list, estimate, l, s, *comm);
            }
            return owning_array(std::move(u.sigma_um), {estimate.rows(), estimate.cols()});
        },
        "observations"_a, "estimate"_a, "loss"_a, py::kw_only(), "probe_spacing"_a = us.probe_spacing,
        "rounds"_a = us.rounds, "cg_tolerance"_a = us.cg_tolerance, "cg_iterations"_a = us.cg_iterations,
        "seed"_a = us.seed, "dense_max_texels"_a = us.dense_max_texels, "comm"_a = py::none(),
        R"doc(
Error bars of `estimate` (a Heightfield recovered from `observations`): the standard deviation
of every height (mean removed), um, a float64 array (rows, cols), from the curvature of `loss`
(the loss it was fitted with: 'poisson:N' uses the Fisher information of N photons per slice;
'amplitude', 'mse', 'cmsle:EPS' a noise variance estimated from the residuals) at the estimate:
the diagonal of the inverse Gauss-Newton matrix G, formed sparse (one forward difference per
texel of each observation's footprint): exact (dense Cholesky) up to dense_max_texels texels
(0...16384), above by coloured probes (texels probe_spacing apart share one, 1...16; rounds
sign draws, 1...64) and conjugate gradients on the formed G (cg_tolerance in (0, 1),
cg_iterations 1...10000). comm: None or an mpi4py communicator (observations: this rank's
share; every rank gets the same map). uncertainty.h, docs/recovery.md "Error bars".
)doc");
}

}  // namespace wavebrdf::python
