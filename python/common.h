#pragma once
// Shared by the binding files: argument checks that name the Python argument, NumPy arrays in
// (float32 or float64, any strides) and out (owning the library's vectors, no copy), and the
// query with its wavelengths as Python sees it.
//
// Errors: a bad argument raises ValueError "NAME ...; expected ...". The library's
// std::invalid_argument and std::domain_error reach Python as ValueError, std::runtime_error
// (files) as RuntimeError, std::bad_alloc as MemoryError (pybind11's standard translations).
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <array>
#include <memory>
#include <string>
#include <vector>

#include "wavebrdf/brdf.h"
#include "wavebrdf/communicator.h"
#include "wavebrdf/heightfield.h"
#include "wavebrdf/interrupt.h"
#include "wavebrdf/io.h"
#include "wavebrdf/model.h"

namespace wavebrdf::python {

namespace py = pybind11;

// The library's communicator for an mpi4py communicator `comm` (through comm.py2f(),
// communicator_from_fortran_handle); None: null (serial). ValueError for an object without
// py2f(); RuntimeError when the module was built without MPI or MPI is not initialised.
std::shared_ptr<const Communicator> communicator_argument(const py::object& comm);
// The keyword's docstring lines.
extern const char* const kCommDoc;

// Throws py::value_error("NAME = GOT is invalid; expected EXPECTED").
[[noreturn]] void bad_argument(const std::string& name, const std::string& got, const std::string& expected);
std::string format_number(double value);  // wavebrdf::format_shortest (wavebrdf/text.h)

// The RenderOptions of the path= ('auto', 'separable', 'fft', 'direct') and tolerance= (1e-12 …
// 1e-2, relative to the slice peak) keywords; ValueError naming the keyword otherwise.
RenderOptions render_options(const std::string& path, double tolerance);
// Their docstring lines.
extern const char* const kRenderOptionsDoc;

// Scalar checks; each returns its value.
double check_finite(double value, const char* name);
double check_positive(double value, const char* name);                  // finite and > 0
int check_resolution(int resolution, const char* name = "resolution");  // 1 ... 8192

// A float32 or float64 NumPy array (native byte order). Lists and other array-likes (not
// ndarrays) are converted to float64 first; an ndarray of another dtype is a ValueError, so
// nothing is silently rounded or reinterpreted.
py::array float_array(py::handle object, const char* name);
bool is_float32(const py::array& array);
std::string shape_string(const py::array& array);
std::string shape_string(const std::vector<py::ssize_t>& shape);
// Checks ndim (and each extent that is ≥ 0 in `shape`; −1 means any extent).
void check_shape(const py::array& array, const std::vector<py::ssize_t>& shape, const char* name);
// The values in C order as double, through any strides; with `finite`, a non-finite value is a
// ValueError naming its index.
std::vector<double> to_doubles(const py::array& array, const char* name, bool finite = true);

// A 2-D float array of heights in texel units → Heightfield (values copied once, as double).
Heightfield heightfield_from_array(py::handle heights, const char* name, double texel_um, double vscale);

// `size`: N or (rows, cols), 1 ... 16384 per side; ValueError naming `name` otherwise.
std::array<int, 2> size_argument(const py::object& size, const char* name = "size");
// A Heightfield (rescaled to texel_um and vscale when `rescale`), an EXR path (read with
// texel_um and vscale; without the GIL) or a 2-D array of heights in texel units.
Heightfield heightfield_argument(const py::object& object, const char* name, double texel_um, double vscale,
                                 bool rescale);

// The texel width and vertical scale for the heightfield file at `path`: `texel_arg` /
// `vscale_arg` when not None (checked; a Python UserWarning naming both values when the file
// says otherwise), else the file's attributes, else the defaults. Reads the header only.
HeightfieldScale heightfield_file_scale(const std::string& path, const py::object& texel_arg,
                                        const py::object& vscale_arg, double default_texel_um = 1.0,
                                        double default_vscale = 1.0);

// The texel width and vertical scale of a run given `truth` (None, a Heightfield, a file path
// or an array): texel_arg / vscale_arg when not None (checked), else a Heightfield's own or a
// file's attributes (heightfield_file_scale), else default_texel_um and 1.
HeightfieldScale truth_scale(const py::object& truth, const py::object& texel_arg, const py::object& vscale_arg,
                             double default_texel_um);

// A NumPy array that owns `values` (moved, not copied), of the given C-order shape.
template <typename T>
py::array_t<T> owning_array(std::vector<T>&& values, const std::vector<py::ssize_t>& shape) {
    auto* owner = new std::vector<T>(std::move(values));
    py::capsule capsule(owner, [](void* p) { delete static_cast<std::vector<T>*>(p); });
    return py::array_t<T>(shape, owner->data(), capsule);
}
// A read-only NumPy view of memory owned by `base` (which the view keeps alive).
template <typename T>
py::array_t<T> readonly_view(const T* data, const std::vector<py::ssize_t>& shape, py::handle base) {
    py::array_t<T> view(shape, data, base);
    py::detail::array_proxy(view.ptr())->flags &= ~py::detail::npy_api::NPY_ARRAY_WRITEABLE_;
    return view;
}

// The wavelengths of `lambda_um` (one, µm) or `spectral` (an integer N: the library's N
// samples over 0.36–0.83 µm, 1 ≤ N ≤ 256; or a sequence of wavelengths in µm). Both None: 0.5 µm.
std::vector<double> wavelengths(const py::object& lambda_um, const py::object& spectral);
// A projected light direction (wx, wy), finite, |ω_i| < 1.
std::array<double, 2> light_direction(const py::object& light, const char* name = "light");
Model model_from(const std::string& name, const char* argument = "model");

// A query as Python sees it: the library's Query plus its wavelengths.
struct PyQuery {
    Query query;
    std::vector<double> lambdas_um;
    bool spectral = false;  // given as `spectral` (RGB through CIE 1931) rather than `lambda_um`
};
PyQuery make_query(double x_um, double y_um, double sigma_p_um, const py::object& light, const std::string& model,
                   const py::object& lambda_um, const py::object& spectral);

// Registration, one function per binding file.
void bind_heightfield(py::module_& m);
void bind_gabor(py::module_& m);
void bind_brdf(py::module_& m);
void bind_model(py::module_& m);       // model.cpp: Query
void bind_slice_plan(py::module_& m);  // slice_plan.cpp: _SlicePlan
void bind_io(py::module_& m);          // io.cpp: read_slice
void bind_spectrum(py::module_& m);
void bind_loss(py::module_& m);
void bind_observation(py::module_& m);
void bind_observation_file(py::module_& m);
void bind_optim(py::module_& m);
void bind_invert(py::module_& m);
void bind_acquisition(py::module_& m);
void bind_roughness_plan(py::module_& m);
void bind_noise(py::module_& m);
void bind_recover(py::module_& m);
void bind_baseline(py::module_& m);
void bind_generate(py::module_& m);
void bind_recovery_run(py::module_& m);
void bind_uncertainty(py::module_& m);
void bind_surface(py::module_& m);  // surface.cpp: metrology
void bind_conditioning(py::module_& m);
void bind_table(py::module_& m);
void bind_image(py::module_& m);

// For a long library call: releases the GIL and installs an InterruptScope whose poll takes the
// GIL back (every 50 ms of work at most) and checks for signals. On Ctrl-C the handler's
// KeyboardInterrupt is left pending, the library stops within one piece of work and throws
// wavebrdf::Interrupted, and the module's translator (module.cpp) raises the pending
// KeyboardInterrupt. Declare it where `py::gil_scoped_release` would go.
class InterruptibleRelease {
public:
    InterruptibleRelease()
        : m_scope([] {
              py::gil_scoped_acquire acquire;
              return PyErr_CheckSignals() != 0;
          }) {}

private:
    py::gil_scoped_release m_release;  // released first, taken back last
    InterruptScope m_scope;
};

// A Python callback for C++ work that runs without the GIL (long inversions and recoveries).
// step(invoke) takes the GIL, notices Ctrl-C, and when a callback was given calls
// invoke(callback) (which builds the arguments under the GIL); it returns whether the work
// should go on: false when the callback returned False (then stopped()), on Ctrl-C, or when
// the callback raised or returned a non-bool (kept, and raised by rethrow_if_failed() once
// the work has returned).
class ReleasedCallback {
public:
    explicit ReleasedCallback(py::object callback) : m_callback(std::move(callback)) {}

    template <typename Invoke>
    bool step(Invoke&& invoke) {
        py::gil_scoped_acquire acquire;
        if (PyErr_CheckSignals() != 0) return fail();
        if (m_callback.is_none()) return true;
        try {
            const py::object r = invoke(m_callback);
            if (!r.is_none() && !r.cast<bool>()) {
                m_stopped = true;
                return false;
            }
        } catch (py::error_already_set& e) {
            e.restore();  // raised again once the work has stopped
            return fail();
        } catch (const py::cast_error&) {
            PyErr_SetString(PyExc_ValueError,
                            "callback returned a value that is not a bool; expected True, False or None");
            return fail();
        }
        return true;
    }

    bool stopped() const { return m_stopped; }
    // Call with the GIL held, after the work has returned.
    void rethrow_if_failed() const {
        if (m_failed) throw py::error_already_set();
    }

private:
    bool fail() {
        m_failed = true;
        return false;
    }

    py::object m_callback;
    bool m_stopped = false, m_failed = false;
};

}  // namespace wavebrdf::python
