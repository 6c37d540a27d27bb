// Observations (reference slices with their queries) and the loss of a heightfield against
// them with its gradient with respect to the heights (observation.h).
#include "common.h"
#include <pybind11/stl/filesystem.h>
#include "observation_arg.h"
#include "wavebrdf/observation.h"

namespace wavebrdf::python {

using namespace pybind11::literals;

Loss loss_argument(const py::object& loss) {
    if (py::isinstance<py::str>(loss)) return parse_loss(loss.cast<std::string>());
    try {
        return loss.cast<Loss>();
    } catch (const py::cast_error&) {
        throw py::value_error("loss = " + std::string(py::repr(loss)) +
                              " is invalid; expected a Loss or a spec 'cmsle:EPS', 'mse', 'amplitude' or 'poisson:N'");
    }
}

std::vector<Observation> observations_argument(const py::object& observations) {
    if (py::isinstance<Observation>(observations)) return {observations.cast<Observation>()};
    std::vector<Observation> list;
    try {
        list = observations.cast<std::vector<Observation>>();
    } catch (const py::cast_error&) {
        throw py::value_error("observations = " + std::string(py::repr(observations)) +
                              " is invalid; expected an Observation or a list of them");
    }
    if (list.empty()) throw py::value_error("observations is empty; expected at least one Observation");
    return list;
}

py::array observation_array(std::vector<double>&& values, const Observation& o) {
    const int n = o.resolution;
    if (o.channels() == 1) return owning_array(std::move(values), {n, n});
    return owning_array(std::move(values), {n, n, 3});
}

namespace {

Observation make_observation(const PyQuery& q, py::handle reference, py::handle weights) {
    const py::array r = float_array(reference, "reference");
    const bool rgb = q.lambdas_um.size() > 1;
    const bool ok = rgb ? (r.ndim() == 3 && r.shape(2) == 3) : r.ndim() == 2;
    if (!ok || r.shape(0) != r.shape(1) || r.shape(0) < 1)
        throw py::value_error(
            "reference has shape " + shape_string(r) + "; expected " +
            (rgb ? "(n, n, 3) for a spectral query" : "(n, n) for a single-wavelength query (e.g. slice[..., 0])"));
    Observation o;
    o.query = q.query;
    o.lambdas_um = q.lambdas_um;
    o.resolution = check_resolution(static_cast<int>(r.shape(0)), "reference.shape[0]");
    if (weights.is_none()) {
        o.reference = to_reference(to_doubles(r, "reference"));
    } else {
        const py::array w = float_array(weights, "weights");
        if (w.ndim() != 2 || w.shape(0) != r.shape(0) || w.shape(1) != r.shape(1))
            throw py::value_error("weights has shape " + shape_string(w) + "; expected (" + std::to_string(r.shape(0)) +
                                  ", " + std::to_string(r.shape(0)) + "), one weight per pixel of the reference");
        o.weights = to_reference(to_doubles(w, "weights"));
        // A pixel of weight 0 may hold anything (NaN for a dead pixel): validate checks the others.
        o.reference = to_reference(to_doubles(r, "reference", false));
    }
    try {
        validate(o);
    } catch (const std::exception& e) {
        throw py::value_error(e.what());
    }
    return o;
}

// An observation from a slice EXR that wavebrdf wrote (its query in the attributes), as
// `wavebrdf invert --reference` reads one; weights as the constructor's.
Observation observation_from_slice(const std::filesystem::path& path_arg, py::handle weights) {
    const std::string path = path_arg.string();
    SliceFile file;
    {
        py::gil_scoped_release release;
        file = read_slice_exr(path);
    }
    if (!file.attributes)
        throw py::value_error(path +
                              " has no wavebrdf slice attributes (a measured slice?); expected "
                              "Observation(Query(...), reference) with its query, e.g. "
                              "read_slice(path)[0][..., 0] as the reference");
    const SliceAttributes& a = *file.attributes;
    if (file.image.rows != file.image.cols)
        throw py::value_error(path + " is " + std::to_string(file.image.rows) + "x" + std::to_string(file.image.cols) +
                              "; expected a square slice");
    PyQuery q;
    q.query = a.query;
    q.lambdas_um = a.lambdas_um;
    q.spectral = a.lambdas_um.size() > 1;
    const py::ssize_t n = file.image.rows;
    py::array_t<float> image = owning_array(std::move(file.image.data), {n, n, 3});
    // One wavelength: the R channel (R = G = B in the file).
    const py::object reference = q.lambdas_um.size() == 1 ? py::object(image[py::make_tuple(py::ellipsis(), 0)])
                                                          : py::object(image);
    return make_observation(q, reference, weights);
}

PyQuery query_of(const Observation& o) {
    PyQuery q;
    q.query = o.query;
    q.lambdas_um = o.lambdas_um;
    q.spectral = o.lambdas_um.size() > 1;
    return q;
}

}  // namespace

void bind_observation(py::module_& m) {
    py::class_<Observation>(m, "Observation", R"doc(
A reference slice with the query that produced it (an input of observation_loss and invert).

Observation(query, reference, weights=None)
    query      a Query
    reference  the slice, finite: (n, n) for one wavelength, (n, n, 3) linear sRGB for a
               spectral query (may be slightly negative: out-of-gamut colours); n = the
               resolution (1...8192); stored rounded to float32
    weights    None (every pixel weighs 1) or (n, n) per-pixel weights, finite, >= 0, not all 0:
               the loss is the weighted mean over pixels, so a pixel of weight 0 (dead,
               saturated, unmeasured) changes neither the loss nor its gradient, and its
               reference value may be anything, NaN included; stored as float32
)doc")
        .def(py::init(&make_observation), "query"_a, "reference"_a, "weights"_a = py::none())
        .def_static("from_slice", &observation_from_slice, "path"_a, "weights"_a = py::none(),
                    "The observation of a slice EXR written by wavebrdf (render --out, genbrdf -o, a run's\n"
                    "reference_ slices): its query and wavelengths from the file's attributes, as `wavebrdf\n"
                    "invert --reference` reads it; weights as the constructor's. ValueError for a file\n"
                    "without the attributes (a measured slice: use Observation(query, reference)).")
        .def_property_readonly(
            "weights",
            [](py::object self) -> py::object {
                const auto& o = self.cast<const Observation&>();
                if (o.weights.empty()) return py::none();
                const py::ssize_t n = o.resolution;
                return readonly_view<float>(o.weights.data(), {n, n}, self);
            },
            "the per-pixel weights, a read-only float32 (n, n) view, or None (every pixel weighs 1)")
        .def_property_readonly("query", &query_of)
        .def_property_readonly("resolution", [](const Observation& o) { return o.resolution; })
        .def_property_readonly("channels", &Observation::channels, "1 (one wavelength) or 3 (RGB)")
        .def_property_readonly("lambdas_um", [](const Observation& o) { return o.lambdas_um; })
        .def_property_readonly(
            "reference",
            [](py::object self) {
                const auto& o = self.cast<const Observation&>();
                const py::ssize_t n = o.resolution;
                return o.channels() == 1 ? readonly_view<float>(o.reference.data(), {n, n}, self)
                                         : readonly_view<float>(o.reference.data(), {n, n, 3}, self);
            },
            "the reference slice, a read-only float32 view (stored in float, as in the slice files)")
        .def(
            "render",
            [](const Observation& o, const Heightfield& hf, const std::string& path, double tolerance) {
                const RenderOptions options = render_options(path, tolerance);
                std::vector<double> v;
                {
                    InterruptibleRelease release;
                    v = render_observation(hf, o, options);
                }
                return observation_array(std::move(v), o);
            },
            "heightfield"_a, py::kw_only(), "path"_a = "auto", "tolerance"_a = 1e-6,
            "What this observation would see of `heightfield`, shaped like the reference (float64); path and\n"
            "tolerance as wavebrdf.render_slice's.")
        .def("__repr__", [](const Observation& o) {
            return "Observation(" + std::to_string(o.resolution) + "x" + std::to_string(o.resolution) + "x" +
                   std::to_string(o.channels()) + ", " + std::to_string(o.lambdas_um.size()) + " wavelength(s), at (" +
                   format_number(o.query.x_um) + ", " + format_number(o.query.y_um) + ") um)";
        });

    m.def(
        "observation_loss",
        [](const Heightfield& hf, const py::object& observations, const py::object& loss, const std::string& path,
           double tolerance) {
            const std::vector<Observation> list = observations_argument(observations);
            const Loss l = loss_argument(loss);
            const RenderOptions options = render_options(path, tolerance);
            std::vector<double> gradient;
            double value = 0.0;
            {
                InterruptibleRelease release;
                value = observation_loss(hf, list, l, &gradient, options);
            }
            return py::make_tuple(value, owning_array(std::move(gradient), {hf.rows(), hf.cols()}));
        },
        "heightfield"_a, "observations"_a, "loss"_a = "cmsle:1", py::kw_only(), "path"_a = "auto", "tolerance"_a = 1e-6,
        R"doc(
The mean over observations of loss(render(heightfield), reference) and its gradient with
respect to the heightfield's values (texel units, float64 (rows, cols)), in double precision:
(value, gradient). loss: a Loss or its spec ('cmsle:EPS', 'mse', 'amplitude', 'poisson:N').
path and tolerance as wavebrdf.render_slice's.
)doc");
}

}  // namespace wavebrdf::python
