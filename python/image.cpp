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

// The scene's keyword arguments, shared by render_image and image_gradient.
#define WB_IMAGE_SCENE_PARAMS                                                                             \
    const py::object &plane_size_um, const py::object &camera, const py::object &look_at, double fov_deg, \
        const py::object &resolution, const py::object &point_light, const py::object &directional_light, \
        const py::object &lambda_um, const py::object &spectral, const py::object &up, bool orthographic, \
        double view_width_um, double rotation_deg, const std::string &model, double sigma_p_um,           \
        double prune_tolerance, double power_w, double irradiance, const py::object &blackbody_k,         \
        const py::object &texel_um, const py::object &vscale, double max_memory_gb,                       \
        const py::object &sphere_radius_um, const py::object &cylinder_radius_um,                         \
        const py::object &cylinder_length_um, const std::string &precision, const py::object &disc_light, \
        int disc_order
#define WB_IMAGE_SCENE_ARGS                                                                                       \
    plane_size_um, camera, look_at, fov_deg, resolution, point_light, directional_light, lambda_um, spectral, up, \
        orthographic, view_width_um, rotation_deg, model, sigma_p_um, prune_tolerance, power_w, irradiance,       \
        blackbody_k, texel_um, vscale, max_memory_gb, sphere_radius_um, cylinder_radius_um, cylinder_length_um,   \
        precision, disc_light, disc_order
#define WB_IMAGE_SCENE_KW                                                                                           \
    "plane_size_um"_a = py::none(), "camera"_a, "look_at"_a = py::make_tuple(0.0, 0.0, 0.0), "fov_deg"_a = 30.0,    \
    "resolution"_a = 256, "point_light"_a = py::none(), "directional_light"_a = py::none(),                         \
    "lambda_um"_a = py::none(), "spectral"_a = py::none(), "up"_a = py::none(), "orthographic"_a = false,           \
    "view_width_um"_a = 0.0, "rotation_deg"_a = 0.0, "model"_a = "OHS", "sigma_p_um"_a = 0.0,                       \
    "prune_tolerance"_a = 1e-4, "power_w"_a = 1.0, "irradiance"_a = 1.0, "blackbody_k"_a = py::none(),              \
    "texel_um"_a = py::none(), "vscale"_a = py::none(), "max_memory_gb"_a = 0.0, "sphere_radius_um"_a = py::none(), \
    "cylinder_radius_um"_a = py::none(), "cylinder_length_um"_a = py::none(), "precision"_a = "double",             \
    "disc_light"_a = py::none(), "disc_order"_a = 4

Heightfield scene_heightfield(const py::object& heightfield, const py::object& texel_um, const py::object& vscale) {
    if (py::isinstance<py::str>(heightfield)) {
        const std::string path = heightfield.cast<std::string>();
        const HeightfieldScale scale = heightfield_file_scale(path, texel_um, vscale);
        py::gil_scoped_release release;
        return read_heightfield_exr(path, scale.texel_um, scale.vscale);
    }
    const double w = texel_um.is_none() ? 1.0 : check_positive(texel_um.cast<double>(), "texel_um");
    const double v = vscale.is_none() ? 1.0 : check_finite(vscale.cast<double>(), "vscale");
    return heightfield_argument(heightfield, "heightfield", w, v, !texel_um.is_none() || !vscale.is_none());
}

ImageOptions scene_options(WB_IMAGE_SCENE_PARAMS) {
    (void)texel_um;  // the heightfield's (scene_heightfield)
    (void)vscale;
    ImageOptions o;
    const int shapes = int(!plane_size_um.is_none()) + int(!sphere_radius_um.is_none()) +
                       int(!cylinder_radius_um.is_none());
    if (shapes != 1)
        bad_argument("sample", std::to_string(shapes) + " shapes given",
                     "exactly one of plane_size_um, sphere_radius_um, cylinder_radius_um (with cylinder_length_um)");
    if (!cylinder_radius_um.is_none() && cylinder_length_um.is_none())
        bad_argument("cylinder_length_um", "None", "the cylinder's length in um");
    if (cylinder_radius_um.is_none() && !cylinder_length_um.is_none())
        bad_argument("cylinder_length_um", std::string(py::repr(cylinder_length_um)),
                     "None without cylinder_radius_um");
    if (!sphere_radius_um.is_none()) {
        o.shape = SampleShape::Sphere;
        o.radius_um = sphere_radius_um.cast<double>();
    } else if (!cylinder_radius_um.is_none()) {
        o.shape = SampleShape::Cylinder;
        o.radius_um = cylinder_radius_um.cast<double>();
        o.length_um = cylinder_length_um.cast<double>();
    } else if (py::isinstance<py::sequence>(plane_size_um)) {
        const auto v = plane_size_um.cast<std::vector<double>>();
        if (v.size() != 2) bad_argument("plane_size_um", std::string(py::repr(plane_size_um)), "W or (W, H)");
        o.plane_size_um = {v[0], v[1]};
    } else {
        const double w = plane_size_um.cast<double>();
        o.plane_size_um = {w, w};
    }
    if (precision != "double" && precision != "float")
        bad_argument("precision", "'" + precision + "'", "'double' or 'float'");
    o.single_precision = precision == "float";
    o.camera.position = vec3_argument(camera, "camera");
    o.camera.look_at = vec3_argument(look_at, "look_at");
    if (!up.is_none()) {
        o.camera.up = vec3_argument(up, "up");
        if (o.camera.up == std::array<double, 3>{{0.0, 0.0, 0.0}})
            bad_argument("up", std::string(py::repr(up)),
                         "a nonzero direction (None: +z, or -x looking straight down)");
    }
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
    // Disc lights: (x, y, z, r) or a list of them.
    if (!disc_light.is_none()) {
        const py::sequence seq = disc_light.cast<py::sequence>();
        std::vector<py::object> items;
        if (seq.size() > 0 && !py::isinstance<py::sequence>(seq[0]))
            items.push_back(disc_light);
        else
            for (const py::handle item : seq) items.push_back(py::reinterpret_borrow<py::object>(item));
        for (const py::object& item : items) {
            std::vector<double> v;
            try {
                v = item.cast<std::vector<double>>();
            } catch (const py::cast_error&) {}
            if (v.size() != 4) bad_argument("disc_light", std::string(py::repr(item)), "(x, y, z, r) in um");
            ImageLight l = base;
            l.kind = LightKind::Disc;
            l.vector = {check_finite(v[0], "disc_light"), check_finite(v[1], "disc_light"),
                        check_finite(v[2], "disc_light")};
            l.radius_um = v[3];
            l.disc_order = disc_order;
            o.lights.push_back(l);
        }
    }
    return o;
}

}  // namespace

void bind_image(py::module_& m) {
    m.def(
        "render_image",
        [](const py::object& heightfield, WB_IMAGE_SCENE_PARAMS, const std::string& dtype) -> py::object {
            const Heightfield hf = scene_heightfield(heightfield, texel_um, vscale);
            const ImageOptions o = scene_options(WB_IMAGE_SCENE_ARGS);
            if (dtype != "float32" && dtype != "float64")
                bad_argument("dtype", "'" + dtype + "'", "'float32' (as the EXR) or 'float64' (before rounding)");
            RgbImage image;
            std::vector<double> values;
            {
                InterruptibleRelease release;
                const PreparedImage prepared = prepare_image(hf, o);
                if (dtype == "float64")
                    values = render_image_values(hf, prepared);
                else
                    image = render_image(hf, prepared);
            }
            const py::ssize_t rows = o.camera.rows, cols = o.camera.cols;
            if (dtype == "float64") return owning_array(std::move(values), {rows, cols, 3});
            return owning_array(std::move(image.data), {rows, cols, 3});
        },
        "heightfield"_a, py::kw_only(), WB_IMAGE_SCENE_KW, "dtype"_a = "float32",
        "A camera picture of a sample carrying the heightfield (docs/image.md), as `wavebrdf image` renders it:\n"
        "an array (rows, cols, 3) of linear sRGB radiance in W/(m^2 sr): float32 as the EXR (the default), or\n"
        "dtype='float64' for the values before that rounding.\n\n"
        "heightfield: a Heightfield, an EXR path or a 2-D array of heights in texel widths.\n"
        "plane_size_um: W or (W, H), the plate (x by y) centred at the origin, the heightfield tiled on it; or\n"
        "sphere_radius_um=R (a sphere about the origin, poles on y), or cylinder_radius_um=R with\n"
        "cylinder_length_um=L (about the x axis, centred): exactly one of them (docs/image.md states the mappings).\n"
        "camera, look_at, up: (x, y, z) in um; z is the plate's normal, x/y the heightfield's rows/columns.\n"
        "fov_deg: pinhole field of view across the rows; orthographic=True with view_width_um instead.\n"
        "resolution: N or (rows, cols).\n"
        "point_light: (x, y, z) um or a list of them; directional_light: direction(s) towards the light;\n"
        "disc_light: (x, y, z, r) um, a Lambertian disc facing the origin, integrated by disc_order n\n"
        "(n Gauss-Legendre radii x 2n angles).\n"
        "lambda_um: one wavelength (a laser) or spectral=K wavelengths over 0.36-0.83 um.\n"
        "sigma_p_um: every pixel's footprint (0: from the pixel's projected size).\n"
        "prune_tolerance: kernel pruning bound relative to each pixel's largest possible value (0: full sum).\n"
        "precision: 'double' or 'float' (the sum in single precision, as the CLI's --precision float).\n"
        "power_w (point), irradiance (directional, W/m^2), blackbody_k (spectrum; None: white).");
    m.def(
        "image_gradient",
        [](const py::object& heightfield, const py::object& dL_dimage, WB_IMAGE_SCENE_PARAMS) {
            const Heightfield hf = scene_heightfield(heightfield, texel_um, vscale);
            const ImageOptions o = scene_options(WB_IMAGE_SCENE_ARGS);
            const auto weights = dL_dimage.cast<py::array_t<double, py::array::c_style | py::array::forcecast>>();
            if (weights.ndim() != 3 || weights.shape(0) != o.camera.rows || weights.shape(1) != o.camera.cols ||
                weights.shape(2) != 3) {
                std::string shape;
                for (py::ssize_t k = 0; k < weights.ndim(); ++k)
                    shape += (k ? ", " : "") + std::to_string(weights.shape(k));
                bad_argument("dL_dimage", "an array of shape (" + shape + ")",
                             "(" + std::to_string(o.camera.rows) + ", " + std::to_string(o.camera.cols) + ", 3)");
            }
            std::vector<double> w(weights.data(), weights.data() + weights.size());
            std::vector<double> gradient;
            {
                InterruptibleRelease release;
                const PreparedImage prepared = prepare_image(hf, o);
                image_gradient(hf, prepared, w, gradient);
            }
            return owning_array(std::move(gradient), {py::ssize_t(hf.rows()), py::ssize_t(hf.cols())});
        },
        "heightfield"_a, "dL_dimage"_a, py::kw_only(), WB_IMAGE_SCENE_KW,
        "The gradient of a loss of render_image's picture with respect to the heights: given dL/dimage (rows, cols,\n"
        "3), returns dL/dh (the heightfield's rows, cols; per height value in texel widths, as the array or file\n"
        "holds it), through the point evaluator's adjoint (about twice the forward pass). The scene's keywords are\n"
        "render_image's; the gradient is of the double-precision picture (render_image(..., dtype='float64')).");
}

#undef WB_IMAGE_SCENE_PARAMS
#undef WB_IMAGE_SCENE_ARGS
#undef WB_IMAGE_SCENE_KW

}  // namespace wavebrdf::python
