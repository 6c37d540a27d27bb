// Error bars of a recovered heightfield (uncertainty.h): height_uncertainty.

#include "common.h"
#include "recovery_args.h"
#include "wavebrdf/uncertainty.h"

namespace wavebrdf::python {

using namespace pybind11::literals;

namespace {
constexpr int k_max_matrix_texels = 16384;  // 2 GiB of doubles
}  // namespace

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
    m.def(
        "gauss_newton_matrix",
        [](const py::object& observations, const Heightfield& estimate, const py::object& loss, double step_um,
           const py::object& comm_arg) {
            const std::shared_ptr<const Communicator> comm = ranks_argument(comm_arg);
            const std::vector<Observation> list = observations_or_file(observations);
            const Loss l = loss_argument(loss);
            const int n = estimate.rows() * estimate.cols();
            if (n > k_max_matrix_texels)
                bad_argument("estimate", std::to_string(estimate.rows()) + "x" + std::to_string(estimate.cols()),
                             "at most " + std::to_string(k_max_matrix_texels) + " texels (G is texels^2 doubles)");
            std::vector<double> g;
            {
                py::gil_scoped_release release;
                g = GaussNewtonOperator(list, estimate, l, step_um, *comm).band().dense();
            }
            return owning_array(std::move(g), {n, n});
        },
        "observations"_a, "estimate"_a, "loss"_a, py::kw_only(), "step_um"_a = us.step_um, "comm"_a = py::none(),
        R"doc(
The Gauss-Newton matrix G of `loss` at `estimate` (a Heightfield fitted to `observations`),
dense, 1/um^2, a float64 array (n, n) over the texels in row-major order (n = rows x cols, at
most 16384): the matrix height_uncertainty inverts ('poisson:N': the Fisher information of the
photon counts; G times a constant vector is 0: the mean height is not observed). Its
pseudo-inverse is the heights' covariance, so f^H G^+ f / n is the variance of a Fourier mode f
(experiments/2026-11-30-photon-plan-variance.md). step_um: the forward differences' step (> 0);
comm as height_uncertainty's. uncertainty.h.
)doc");
}

}  // namespace wavebrdf::python
