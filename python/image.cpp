// Camera images (image.h): wavebrdf.render_image, the same run as `wavebrdf image`. This file
// only converts and validates the arguments.
#include "common.h"
#include "wavebrdf/image.h"
#include "wavebrdf/spectrum.h"

namespace wavebrdf::python {

using namespace pybind11::literals;

namespace {

std::array<double, 3> vec3_argument(const py::object& object, const char* name) {
    std::vector<double> v;
    try {
        v = object.cast<std::vector<double>>();
    } catch (const py::cast_error&) {
        bad_argument(name, std::string(py::repr(object)), "three numbers (x, y, z)");
    }
    if (v.size() != 3) bad_argument(name, std::string(py::repr(object)), "three numbers (x, y, z)");
    for (double x : v) check_finite(x, name);
    return {v[0], v[1], v[2]};
}

// None, one (x, y, z) or a list of them.
std::vector<std::array<double, 3>> vec3_list(const py::object& object, const char* name) {
    std::vector<std::array<double, 3>> out;
    if (object.is_none()) return out;
    const py::sequence seq = object.cast<py::sequence>();
    if (seq.size() > 0 && !py::isinstance<py::sequence>(seq[0])) {
        out.push_back(vec3_argument(object, name));
        return out;
    }
    for (const py::handle item : seq) out.push_back(vec3_argument(py::reinterpret_borrow<py::object>(item), name));
    return out;
}

}  // namespace

void bind_image(py::module_& m) {
    m.def(
        "render_image",
        [](const py::object& heightfield, const py::object& plane_size_um, const py::object& camera,
           const py::object& look_at, double fov_deg, const py::object& resolution, const py::object& point_light,
           const py::object& directional_light, const py::object& lambda_um, const py::object& spectral,
           const py::object& up, bool orthographic, double view_width_um, double rotation_deg, const std::string& model,
           double sigma_p_um, double prune_tolerance, double power_w, double irradiance, const py::object& blackbody_k,
           const py::object& texel_um, const py::object& vscale, double max_memory_gb) {
            Heightfield hf = [&] {
                if (py::isinstance<py::str>(heightfield)) {
                    const std::string path = heightfield.cast<std::string>();
                    const HeightfieldScale scale = heightfield_file_scale(path, texel_um, vscale);
                    py::gil_scoped_release release;
                    return read_heightfield_exr(path, scale.texel_um, scale.vscale);
                }
                const double w = texel_um.is_none() ? 1.0 : check_positive(texel_um.cast<double>(), "texel_um");
                const double v = vscale.is_none() ? 1.0 : check_finite(vscale.cast<double>(), "vscale");
                return heightfield_argument(heightfield, "heightfield", w, v, !texel_um.is_none() || !vscale.is_none());
            }();
            ImageOptions o;
            if (py::isinstance<py::sequence>(plane_size_um)) {
                const auto v = plane_size_um.cast<std::vector<double>>();
                if (v.size() != 2) bad_argument("plane_size_um", std::string(py::repr(plane_size_um)), "W or (W, H)");
                o.plane_size_um = {v[0], v[1]};
            } else {
                const double w = plane_size_um.cast<double>();
                o.plane_size_um = {w, w};
            }
            o.camera.position = vec3_argument(camera, "camera");
            o.camera.look_at = vec3_argument(look_at, "look_at");
            if (!up.is_none()) o.camera.up = vec3_argument(up, "up");
            o.camera.fov_deg = fov_deg;
            o.camera.orthographic = orthographic;
            o.camera.view_width_um = view_width_um;
            const std::array<int, 2> size = size_argument(resolution, "resolution");
            o.camera.rows = size[0];
            o.camera.cols = size[1];
            o.rotation_deg = rotation_deg;
            o.model = model_from(model);
            o.sigma_p_um = sigma_p_um;
            o.prune_tolerance = prune_tolerance;
            o.max_memory_gb = max_memory_gb;
            o.lambdas_um = wavelengths(lambda_um, spectral);
            ImageLight base;
            base.power_w = power_w;
            base.irradiance_w_m2 = irradiance;
            if (!blackbody_k.is_none()) {
                base.spectrum = LightSpectrum::Blackbody;
                base.temperature_k = blackbody_k.cast<double>();
            }
            for (const auto& p : vec3_list(point_light, "point_light")) {
                ImageLight l = base;
                l.kind = LightKind::Point;
                l.vector = p;
                o.lights.push_back(l);
            }
            for (const auto& d : vec3_list(directional_light, "directional_light")) {
                ImageLight l = base;
                l.kind = LightKind::Directional;
                l.vector = d;
                o.lights.push_back(l);
            }
            RgbImage image;
            {
                InterruptibleRelease release;
                const PreparedImage prepared = prepare_image(hf, o);
                image = render_image(hf, prepared);
            }
            const py::ssize_t rows = image.rows, cols = image.cols;
            return owning_array(std::move(image.data), {rows, cols, 3});
        },
        "heightfield"_a, py::kw_only(), "plane_size_um"_a, "camera"_a, "look_at"_a = py::make_tuple(0.0, 0.0, 0.0),
        "fov_deg"_a = 30.0, "resolution"_a = 256, "point_light"_a = py::none(), "directional_light"_a = py::none(),
        "lambda_um"_a = py::none(), "spectral"_a = py::none(), "up"_a = py::none(), "orthographic"_a = false,
        "view_width_um"_a = 0.0, "rotation_deg"_a = 0.0, "model"_a = "OHS", "sigma_p_um"_a = 0.0,
        "prune_tolerance"_a = 1e-4, "power_w"_a = 1.0, "irradiance"_a = 1.0, "blackbody_k"_a = py::none(),
        "texel_um"_a = py::none(), "vscale"_a = py::none(), "max_memory_gb"_a = 0.0,
        "A camera picture of a plate carrying the heightfield (docs/image.md), as `wavebrdf image` renders it:\n"
        "a float32 array (rows, cols, 3) of linear sRGB radiance in W/(m^2 sr).\n\n"
        "heightfield: a Heightfield, an EXR path or a 2-D array of heights in texel widths.\n"
        "plane_size_um: W or (W, H), the plate (x by y) centred at the origin, the heightfield tiled on it.\n"
        "camera, look_at, up: (x, y, z) in um; z is the plate's normal, x/y the heightfield's rows/columns.\n"
        "fov_deg: pinhole field of view across the rows; orthographic=True with view_width_um instead.\n"
        "resolution: N or (rows, cols).\n"
        "point_light: (x, y, z) um or a list of them; directional_light: direction(s) towards the light.\n"
        "lambda_um: one wavelength (a laser) or spectral=K wavelengths over 0.36-0.83 um.\n"
        "sigma_p_um: every pixel's footprint (0: from the pixel's projected size).\n"
        "prune_tolerance: kernel pruning bound relative to each pixel's largest possible value (0: full sum).\n"
        "power_w (point), irradiance (directional, W/m^2), blackbody_k (spectrum; None: white).");
}

}  // namespace wavebrdf::python
