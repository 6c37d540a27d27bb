#include "common.h"

#include <algorithm>

#include <cmath>

#include "wavebrdf/io.h"
#include "wavebrdf/render_options.h"
#include "wavebrdf/spectrum.h"
#include "wavebrdf/text.h"

namespace wavebrdf::python {

std::shared_ptr<const Communicator> communicator_argument(const py::object& comm) {
    if (comm.is_none()) return nullptr;
    if (!py::hasattr(comm, "py2f"))
        bad_argument("comm", std::string(py::repr(comm)), "None or an mpi4py communicator (mpi4py.MPI.Comm)");
    return communicator_from_fortran_handle(comm.attr("py2f")().cast<long long>());
}

const char* const kCommDoc =
    "comm          None (default: this process alone) or an mpi4py communicator (e.g.\n"
    "              mpi4py.MPI.COMM_WORLD): the work is split over its ranks (docs/scale.md);\n"
    "              every rank must make the same call.\n";

using namespace pybind11::literals;

std::string format_number(double value) { return format_shortest(value); }

void bad_argument(const std::string& name, const std::string& got, const std::string& expected) {
    throw py::value_error(name + " = " + got + " is invalid; expected " + expected);
}

RenderOptions render_options(const std::string& path, double tolerance) {
    RenderOptions options;
    options.path = parse_render_path(path, "path");  // std::invalid_argument: ValueError
    validate_render_tolerance(tolerance, "tolerance");
    options.tolerance = tolerance;
    return options;
}

const char* const kRenderOptionsDoc =
    R"doc(path        'auto' (chosen by cost), 'separable' (matrix products), 'fft' (the FFT engine) or
            'direct' (every pixel sums every kernel); a path the model has not is a ValueError
tolerance   separable (GHS, RGHS, Kirchhoff) and fft paths: error bound relative to the slice
            peak, 1e-12 to 1e-2 (default 1e-6)
)doc";

double check_finite(double value, const char* name) {
    if (!std::isfinite(value)) bad_argument(name, format_number(value), "a finite number");
    return value;
}

double check_positive(double value, const char* name) {
    if (!std::isfinite(value) || value <= 0.0) bad_argument(name, format_number(value), "a finite number > 0");
    return value;
}

int check_resolution(int resolution, const char* name) {
    if (resolution < 1 || resolution > 8192)
        bad_argument(name, std::to_string(resolution), "a slice size from 1 to 8192 pixels");
    return resolution;
}

bool is_float32(const py::array& array) { return array.dtype().equal(py::dtype::of<float>()); }

py::array float_array(py::handle object, const char* name) {
    if (!py::isinstance<py::array>(object)) {
        // Lists, tuples, CPU tensors: convert (a copy) to float64.
        try {
            py::module_ numpy = py::module_::import("numpy");
            return numpy.attr("asarray")(object, "dtype"_a = "float64");
        } catch (py::error_already_set& e) {
            if (!e.matches(PyExc_TypeError) && !e.matches(PyExc_ValueError)) throw;
            throw py::value_error(std::string(name) + " is not an array of numbers (" +
                                  std::string(py::str(py::type::of(object).attr("__name__"))) +
                                  "); expected a float32 or float64 NumPy array");
        }
    }
    py::array array = py::reinterpret_borrow<py::array>(object);
    if (!array.dtype().equal(py::dtype::of<float>()) && !array.dtype().equal(py::dtype::of<double>()))
        throw py::value_error(std::string(name) + " has dtype " + std::string(py::str(array.dtype())) +
                              "; expected float32 or float64 (native byte order)");
    return array;
}

std::string shape_string(const std::vector<py::ssize_t>& shape) {
    std::string s = "(";
    for (std::size_t i = 0; i < shape.size(); ++i) {
        if (i) s += ", ";
        s += shape[i] < 0 ? std::string("any") : std::to_string(shape[i]);
    }
    if (shape.size() == 1) s += ",";
    return s + ")";
}

std::string shape_string(const py::array& array) {
    return shape_string(std::vector<py::ssize_t>(array.shape(), array.shape() + array.ndim()));
}

void check_shape(const py::array& array, const std::vector<py::ssize_t>& shape, const char* name) {
    bool ok = array.ndim() == static_cast<py::ssize_t>(shape.size());
    for (std::size_t i = 0; ok && i < shape.size(); ++i)
        ok = shape[i] < 0 || array.shape(static_cast<py::ssize_t>(i)) == shape[i];
    if (!ok)
        throw py::value_error(std::string(name) + " has shape " + shape_string(array) + "; expected " +
                              shape_string(shape));
}

namespace {

template <typename T>
void gather(const char* base, const py::ssize_t* shape, const py::ssize_t* strides, py::ssize_t ndim, double*& out) {
    if (ndim == 0) {
        *out++ = static_cast<double>(*reinterpret_cast<const T*>(base));
        return;
    }
    for (py::ssize_t i = 0; i < shape[0]; ++i) gather<T>(base + i * strides[0], shape + 1, strides + 1, ndim - 1, out);
}

}  // namespace

std::vector<double> to_doubles(const py::array& array, const char* name, bool finite) {
    std::vector<double> values(static_cast<std::size_t>(array.size()));
    double* out = values.data();
    const char* base = static_cast<const char*>(array.data());
    if (is_float32(array))
        gather<float>(base, array.shape(), array.strides(), array.ndim(), out);
    else
        gather<double>(base, array.shape(), array.strides(), array.ndim(), out);
    if (finite)
        for (std::size_t k = 0; k < values.size(); ++k)
            if (!std::isfinite(values[k])) {
                // The index in the array's own shape, e.g. [3, 4].
                std::string index;
                std::size_t rest = k;
                for (py::ssize_t d = array.ndim() - 1; d >= 0; --d) {
                    const auto extent = static_cast<std::size_t>(array.shape(d));
                    index = std::to_string(rest % extent) + (index.empty() ? "" : ", ") + index;
                    rest /= extent;
                }
                throw py::value_error(std::string(name) + "[" + index + "] = " + format_number(values[k]) +
                                      " is not finite; expected finite values");
            }
    return values;
}

Heightfield heightfield_from_array(py::handle object, const char* name, double texel_um, double vscale) {
    const py::array heights = float_array(object, name);
    if (heights.ndim() != 2 || heights.size() == 0)
        throw py::value_error(std::string(name) + " has shape " + shape_string(heights) +
                              "; expected a non-empty 2-D array (rows, cols) of heights in texel units");
    check_positive(texel_um, "texel_um");
    check_finite(vscale, "vscale");
    return Heightfield(static_cast<int>(heights.shape(0)), static_cast<int>(heights.shape(1)),
                       to_doubles(heights, name), texel_um, vscale);
}

std::array<int, 2> size_argument(const py::object& size, const char* name) {
    std::array<int, 2> rc{};
    try {
        // Any integer, NumPy's too (np.int64 is no Python int but has __index__); not bool.
        if (!py::isinstance<py::bool_>(size) && PyIndex_Check(size.ptr())) {
            const long long v = py::reinterpret_steal<py::int_>(PyNumber_Index(size.ptr())).cast<long long>();
            rc[0] = rc[1] = static_cast<int>(std::clamp<long long>(v, -1, 1 << 30));
        } else {
            const auto v = size.cast<std::vector<int>>();
            if (v.size() != 2) throw py::cast_error();
            rc = {v[0], v[1]};
        }
    } catch (const py::cast_error&) {
        throw py::value_error(std::string(name) + " = " + std::string(py::repr(size)) +
                              " is invalid; expected N or (rows, cols)");
    }
    if (rc[0] < 1 || rc[1] < 1 || rc[0] > 16384 || rc[1] > 16384)
        throw py::value_error(std::string(name) + " = " + std::string(py::repr(size)) +
                              " is out of range; expected 1 to 16384 per side");
    return rc;
}

Heightfield heightfield_argument(const py::object& object, const char* name, double texel_um, double vscale,
                                 bool rescale) {
    if (py::isinstance<Heightfield>(object)) {
        const auto& hf = object.cast<const Heightfield&>();
        return rescale ? hf.with_scale(texel_um, vscale) : hf;
    }
    if (py::isinstance<py::str>(object)) {
        const std::string path = object.cast<std::string>();
        py::gil_scoped_release release;
        return read_heightfield_exr(path, texel_um, vscale);
    }
    return heightfield_from_array(object, name, texel_um, vscale);
}

HeightfieldScale heightfield_file_scale(const std::string& path, const py::object& texel_arg,
                                        const py::object& vscale_arg, double default_texel_um, double default_vscale) {
    std::optional<double> texel_um, vscale;
    if (!texel_arg.is_none()) texel_um = check_positive(texel_arg.cast<double>(), "texel_um");
    if (!vscale_arg.is_none()) vscale = check_finite(vscale_arg.cast<double>(), "vscale");
    HeightfieldAttributes attributes;
    {
        py::gil_scoped_release release;
        attributes = read_heightfield_attributes(path);
    }
    HeightfieldScale scale = resolve_heightfield_scale(path, attributes, texel_um, vscale, "texel_um", "vscale",
                                                       default_texel_um, default_vscale);
    const py::object warn = py::module_::import("warnings").attr("warn");
    for (const std::string& w : scale.warnings)
        warn(w, py::module_::import("builtins").attr("UserWarning"), 1);  // 1: the Python line that called us
    return scale;
}

HeightfieldScale truth_scale(const py::object& truth, const py::object& texel_arg, const py::object& vscale_arg,
                             double default_texel_um) {
    if (py::isinstance<py::str>(truth))
        return heightfield_file_scale(truth.cast<std::string>(), texel_arg, vscale_arg, default_texel_um, 1.0);
    const bool object = py::isinstance<Heightfield>(truth);
    HeightfieldScale scale;
    scale.texel_um = texel_arg.is_none() ? (object ? truth.cast<const Heightfield&>().texel_um() : default_texel_um)
                                         : check_positive(texel_arg.cast<double>(), "texel_um");
    scale.vscale = vscale_arg.is_none() ? (object ? truth.cast<const Heightfield&>().vscale() : 1.0)
                                        : check_finite(vscale_arg.cast<double>(), "vscale");
    return scale;
}

std::vector<double> wavelengths(const py::object& lambda_um, const py::object& spectral) {
    if (!lambda_um.is_none() && !spectral.is_none())
        throw py::value_error("lambda_um and spectral exclude each other; expected one of them (or neither: 0.5 um)");
    if (!spectral.is_none()) {
        // An int, or any integer that says so (__index__: NumPy's np.int64, np.int32, ...).
        if (!py::isinstance<py::bool_>(spectral) &&
            (py::isinstance<py::int_>(spectral) || PyIndex_Check(spectral.ptr()))) {
            const long long count = py::module_::import("operator").attr("index")(spectral).cast<long long>();
            if (count < 1 || count > 256)
                bad_argument("spectral", std::to_string(count),
                             "1 to 256 wavelength samples, or a list of wavelengths in um");
            return spectral_wavelengths_um(static_cast<int>(count));
        }
        std::vector<double> list;
        try {
            list = spectral.cast<std::vector<double>>();
        } catch (const py::cast_error&) {
            throw py::value_error("spectral = " + std::string(py::repr(spectral)) +
                                  " is invalid; expected a sample count (int) or a list of wavelengths in um");
        }
        if (list.empty()) bad_argument("spectral", "[]", "at least one wavelength");
        for (double l : list)
            if (!std::isfinite(l) || l <= 0.0)
                bad_argument("spectral", std::string(py::repr(spectral)), "wavelengths that are finite and > 0 (um)");
        return list;
    }
    if (!lambda_um.is_none()) {
        double l = 0.0;
        try {
            l = lambda_um.cast<double>();
        } catch (const py::cast_error&) {
            throw py::value_error("lambda_um = " + std::string(py::repr(lambda_um)) +
                                  " is invalid; expected a wavelength in um");
        }
        check_positive(l, "lambda_um");
        return {l};
    }
    return {0.5};
}

std::array<double, 2> light_direction(const py::object& light, const char* name) {
    std::vector<double> v;
    try {
        v = light.cast<std::vector<double>>();
    } catch (const py::cast_error&) {
        throw py::value_error(std::string(name) + " = " + std::string(py::repr(light)) +
                              " is invalid; expected a pair (wx, wy)");
    }
    if (v.size() != 2)
        throw py::value_error(std::string(name) + " = " + std::string(py::repr(light)) +
                              " is invalid; expected a pair (wx, wy)");
    if (!std::isfinite(v[0]) || !std::isfinite(v[1]) || v[0] * v[0] + v[1] * v[1] >= 1.0)
        bad_argument(name, "(" + format_number(v[0]) + ", " + format_number(v[1]) + ")",
                     "a projected direction towards the light with wx^2 + wy^2 < 1");
    return {v[0], v[1]};
}

Model model_from(const std::string& name, const char* argument) {
    try {
        return parse_model(name);
    } catch (const std::invalid_argument&) {
        bad_argument(argument, "'" + name + "'", "one of 'OHS', 'GHS', 'ROHS', 'RGHS', 'Kirchhoff'");
    }
}

PyQuery make_query(double x_um, double y_um, double sigma_p_um, const py::object& light, const std::string& model,
                   const py::object& lambda_um, const py::object& spectral) {
    PyQuery q;
    q.query.x_um = check_finite(x_um, "x_um");
    q.query.y_um = check_finite(y_um, "y_um");
    q.query.sigma_p_um = check_positive(sigma_p_um, "sigma_p_um");
    q.query.omega_i = light_direction(light);
    q.query.model = model_from(model);
    q.lambdas_um = wavelengths(lambda_um, spectral);
    q.spectral = !spectral.is_none();
    return q;
}

}  // namespace wavebrdf::python
