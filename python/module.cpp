// The compiled part of the Python package: wavebrdf._core (re-exported by wavebrdf/__init__.py).
#include "common.h"
#include "design.h"
#include "design_plate.h"
#include "fabrication.h"
#include "lobe.h"
#include "wavebrdf/communicator.h"
#include "wavebrdf/version.h"

PYBIND11_MODULE(_core, m) {
    using namespace wavebrdf::python;
    m.doc() =
        "wavebrdf's C++ library: wave-optical BRDF slices of heightfields, their gradients, "
        "losses, optimisers, the inverse renderer and heightfield recovery";
    m.attr("__version__") = wavebrdf::k_version;
    bind_heightfield(m);
    bind_io(m);
    bind_model(m);
    bind_brdf(m);
    bind_slice_plan(m);
    bind_spectrum(m);
    bind_gabor(m);
    bind_loss(m);
    bind_observation(m);
    bind_observation_file(m);
    bind_optim(m);
    bind_invert(m);
    bind_acquisition(m);
    bind_roughness_plan(m);
    bind_noise(m);
    bind_recover(m);
    bind_baseline(m);
    bind_generate(m);
    bind_recovery_run(m);
    bind_uncertainty(m);
    bind_table(m);
    bind_lobe(m);
    bind_fabrication(m);
    bind_image(m);
    bind_design(m);
    bind_design_plate(m);
    bind_surface(m);
    bind_conditioning(m);
    // A long call stopped by Ctrl-C (InterruptibleRelease): its poll left the signal handler's
    // exception (KeyboardInterrupt) pending; raise that, or KeyboardInterrupt if none is.
    py::register_exception_translator([](std::exception_ptr p) {
        if (!p) return;
        try {
            std::rethrow_exception(p);
        } catch (const wavebrdf::Interrupted&) {
            if (!PyErr_Occurred()) PyErr_SetNone(PyExc_KeyboardInterrupt);
        }
    });
    // A failure agreed over the ranks (communicator.h): the failing rank raises its own
    // exception (ValueError, KeyboardInterrupt, …: the translators above), the others a
    // RuntimeError with its message ("rank R: …").
    py::register_exception_translator([](std::exception_ptr p) {
        if (!p) return;
        try {
            std::rethrow_exception(p);
        } catch (const wavebrdf::RankFailed& e) {
            if (e.cause()) std::rethrow_exception(e.cause());
            PyErr_SetString(PyExc_RuntimeError, e.what());
        }
    });
}
