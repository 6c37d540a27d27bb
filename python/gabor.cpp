// GaborRep: the binding of GaborRepresentation (gabor.h): the Gabor kernels of a heightfield
// within one footprint and the inverse transform (heights_from_kernels); conversion only.
#include <cmath>
#include <limits>

#include "common.h"
#include "wavebrdf/gabor.h"

namespace wavebrdf::python {

using namespace pybind11::literals;

namespace {

py::array_t<double> doubles(const std::vector<double>& v, py::handle owner) {
    return readonly_view<double>(v.data(), {static_cast<py::ssize_t>(v.size())}, owner);
}

std::vector<double> kernel_heights_argument(const GaborRepresentation& rep, py::handle height_um) {
    if (height_um.is_none()) return rep.kernels.height_um;
    const py::array a = float_array(height_um, "height_um");
    check_shape(a, {static_cast<py::ssize_t>(rep.kernels.size())}, "height_um");
    return to_doubles(a, "height_um");
}

}  // namespace

void bind_gabor(py::module_& m) {
    py::class_<GaborRepresentation> cls(m, "GaborRep", R"doc(
The Gabor kernels of a heightfield that fall within 3 sigma_p of a footprint centre (the
model's cut; docs/model.md §3-4), independent of wavelength and directions: one kernel
per texel, at its nearest periodic image. Arrays are read-only float64 views (kernel order):

    row, col        texel (i, j) of each kernel (int32)
    dx_um, dy_um    kernel centre minus footprint centre, um
    weight          footprint window weight times kernel area c_k w^2, um
    height_um       kernel height H_k = vscale * texel_um * h[i, j], um
    slope_x/_y      dimensionless slope s_k (periodic central differences of h, times vscale)

GaborRep(heightfield, query)  or
GaborRep(heightfield, x_um=None, y_um=None, sigma_p_um=10.0)
    x_um, y_um default to the tile centre; sigma_p_um > 0 in um.

The inverse transform ``to_heights`` / ``to_heightfield`` recovers heightfield values from
kernel heights (h = H / (vscale * texel_um)); slopes follow from the heights and are not
independent parameters, so they are not used.
)doc");
    cls.def(py::init([](const Heightfield& hf, const PyQuery& q) {
                return GaborRepresentation(hf, q.query.x_um, q.query.y_um, q.query.sigma_p_um);
            }),
            "heightfield"_a, "query"_a)
        .def(py::init([](const Heightfield& hf, py::object x_um, py::object y_um, double sigma_p_um) {
                 const double x = x_um.is_none() ? 0.5 * hf.period_x_um() : check_finite(x_um.cast<double>(), "x_um");
                 const double y = y_um.is_none() ? 0.5 * hf.period_y_um() : check_finite(y_um.cast<double>(), "y_um");
                 return GaborRepresentation(hf, x, y, check_positive(sigma_p_um, "sigma_p_um"));
             }),
             "heightfield"_a, "x_um"_a = py::none(), "y_um"_a = py::none(), "sigma_p_um"_a = 10.0)
        .def("__len__", [](const GaborRepresentation& r) { return r.kernels.size(); })
        .def_property_readonly(
            "size", [](const GaborRepresentation& r) { return r.kernels.size(); }, "number of kernels")
        .def_property_readonly(
            "x_um", [](const GaborRepresentation& r) { return r.x_um; }, "footprint centre along x, um")
        .def_property_readonly(
            "y_um", [](const GaborRepresentation& r) { return r.y_um; }, "footprint centre along y, um")
        .def_property_readonly(
            "sigma_p_um", [](const GaborRepresentation& r) { return r.sigma_p_um; }, "footprint sigma_p, um")
        .def_property_readonly(
            "sigma_um", [](const GaborRepresentation& r) { return r.kernels.sigma_um; },
            "kernel sigma = texel_um / 2, um")
        .def_property_readonly(
            "shape", [](const GaborRepresentation& r) { return py::make_tuple(r.rows, r.cols); },
            "(rows, cols) of the heightfield")
        .def_property_readonly("texel_um", [](const GaborRepresentation& r) { return r.texel_um; })
        .def_property_readonly("vscale", [](const GaborRepresentation& r) { return r.vscale; })
        .def_property_readonly("row",
                               [](py::object self) {
                                   const auto& r = self.cast<const GaborRepresentation&>();
                                   return readonly_view<int>(r.kernels.row.data(),
                                                             {static_cast<py::ssize_t>(r.kernels.size())}, self);
                               })
        .def_property_readonly("col",
                               [](py::object self) {
                                   const auto& r = self.cast<const GaborRepresentation&>();
                                   return readonly_view<int>(r.kernels.col.data(),
                                                             {static_cast<py::ssize_t>(r.kernels.size())}, self);
                               })
        .def_property_readonly(
            "dx_um",
            [](py::object self) { return doubles(self.cast<const GaborRepresentation&>().kernels.dx_um, self); })
        .def_property_readonly(
            "dy_um",
            [](py::object self) { return doubles(self.cast<const GaborRepresentation&>().kernels.dy_um, self); })
        .def_property_readonly(
            "weight",
            [](py::object self) { return doubles(self.cast<const GaborRepresentation&>().kernels.weight, self); })
        .def_property_readonly(
            "height_um",
            [](py::object self) { return doubles(self.cast<const GaborRepresentation&>().kernels.height_um, self); })
        .def_property_readonly(
            "slope_x",
            [](py::object self) { return doubles(self.cast<const GaborRepresentation&>().kernels.slope_x, self); })
        .def_property_readonly(
            "slope_y",
            [](py::object self) { return doubles(self.cast<const GaborRepresentation&>().kernels.slope_y, self); })
        .def_property_readonly(
            "positions_um",
            [](const GaborRepresentation& r) {
                std::vector<double> p(2 * r.kernels.size());
                for (std::size_t k = 0; k < r.kernels.size(); ++k) {
                    p[2 * k] = r.x_um + r.kernels.dx_um[k];
                    p[2 * k + 1] = r.y_um + r.kernels.dy_um[k];
                }
                return owning_array(std::move(p), {static_cast<py::ssize_t>(r.kernels.size()), 2});
            },
            "(size, 2) kernel centres mu_k = footprint centre + (dx_um, dy_um), um (a new array)")
        .def_property_readonly(
            "covered",
            [](const GaborRepresentation& r) {
                py::array_t<bool> mask({r.rows, r.cols});
                std::fill(mask.mutable_data(), mask.mutable_data() + mask.size(), false);
                for (std::size_t k = 0; k < r.kernels.size(); ++k)
                    mask.mutable_data()[static_cast<std::size_t>(r.kernels.row[k]) * r.cols + r.kernels.col[k]] = true;
                return mask;
            },
            "(rows, cols) bool mask of the texels that have a kernel")
        .def(
            "to_heights",
            [](const GaborRepresentation& r, py::handle height_um, double fill) {
                const std::vector<double> values = r.heights_from_kernels(
                    kernel_heights_argument(r, height_um),
                    std::vector<double>(static_cast<std::size_t>(r.rows) * r.cols, fill));
                return owning_array(std::vector<double>(values), {r.rows, r.cols});
            },
            "height_um"_a = py::none(), "fill"_a = std::numeric_limits<double>::quiet_NaN(), R"doc(
The inverse transform: heightfield values in texel units, h = H_k / (vscale * texel_um), at
each kernel's texel; ``fill`` (default NaN) where no kernel lies. ``height_um`` (length
``size``, um) replaces the kernel heights; default: this representation's own.
)doc")
        .def(
            "to_heightfield",
            [](const GaborRepresentation& r, py::handle height_um, const Heightfield* base) {
                std::vector<double> fill;
                if (base) {
                    if (base->rows() != r.rows || base->cols() != r.cols)
                        throw py::value_error("base is " + std::to_string(base->rows()) + "x" +
                                              std::to_string(base->cols()) + "; expected the GaborRep's " +
                                              std::to_string(r.rows) + "x" + std::to_string(r.cols));
                    fill = base->values();
                } else {
                    fill.assign(static_cast<std::size_t>(r.rows) * r.cols, std::numeric_limits<double>::quiet_NaN());
                }
                const std::vector<double> values = r.heights_from_kernels(kernel_heights_argument(r, height_um), fill);
                if (!base)
                    for (double v : values)
                        if (std::isnan(v))
                            throw py::value_error("the GaborRep covers " + std::to_string(r.kernels.size()) + " of " +
                                                  std::to_string(r.rows * r.cols) +
                                                  " texels; expected base= (a Heightfield) for the others");
                return Heightfield(r.rows, r.cols, values, r.texel_um, r.vscale);
            },
            "height_um"_a = py::none(), "base"_a = nullptr, R"doc(
The inverse transform as a Heightfield (same texel_um and vscale): kernel heights (this
representation's, or ``height_um``) at the covered texels, ``base``'s values elsewhere
(required unless every texel is covered).
)doc")
        .def("__repr__", [](const GaborRepresentation& r) {
            return "GaborRep(" + std::to_string(r.kernels.size()) + " kernels of a " + std::to_string(r.rows) + "x" +
                   std::to_string(r.cols) + " heightfield, centre (" + format_number(r.x_um) + ", " +
                   format_number(r.y_um) + ") um, sigma_p " + format_number(r.sigma_p_um) + " um)";
        });
}

}  // namespace wavebrdf::python
