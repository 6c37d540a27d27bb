// The arguments of the slice functions (slice_args.h).
#include "slice_args.h"

namespace wavebrdf::python {

Scale heights_scale(py::handle heights, const py::object& texel_um, const py::object& vscale) {
    const auto number = [](const py::object& v, const char* name) {
        try {
            return v.cast<double>();
        } catch (const py::cast_error&) {
            throw py::value_error(std::string(name) + " = " + std::string(py::repr(v)) +
                                  " is invalid; expected a number");
        }
    };
    Scale s;
    if (!py::isinstance<Heightfield>(heights)) {
        if (!texel_um.is_none()) s.texel_um = number(texel_um, "texel_um");
        if (!vscale.is_none()) s.vscale = number(vscale, "vscale");
        return s;
    }
    const auto& hf = heights.cast<const Heightfield&>();
    s = {hf.texel_um(), hf.vscale()};
    const auto agree = [&](const py::object& given, double own, const char* name) {
        if (given.is_none()) return;
        const double v = number(given, name);
        if (v != own)
            throw py::value_error(std::string(name) + " = " + format_number(v) + " conflicts with the Heightfield's " +
                                  name + " " + format_number(own) + "; expected no " + name +
                                  " keyword (the Heightfield's own is used) or the same value "
                                  "(Heightfield.with_scale gives another)");
    };
    agree(texel_um, s.texel_um, "texel_um");
    agree(vscale, s.vscale, "vscale");
    return s;
}

Plain plain_arguments(py::handle heights, double texel_um, double vscale, double x_um, double y_um, double sigma_p_um,
                      const py::object& lambda_um, const py::object& spectral, const py::object& light, int resolution,
                      const std::string& model) {
    const py::array h = float_array(heights, "heights");
    const bool single = is_float32(h);
    Heightfield hf = heightfield_from_array(h, "heights", texel_um, vscale);
    check_resolution(resolution);
    return {std::move(hf), single, make_query(x_um, y_um, sigma_p_um, light, model, lambda_um, spectral)};
}

std::vector<double> weights_argument(py::handle weights, int n) {
    const py::array w = float_array(weights, "weights");
    check_shape(w, {n, n, 3}, "weights");
    return slice_weights(w, n, "weights");
}

}  // namespace wavebrdf::python
