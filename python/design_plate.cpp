// design_plate(): `wavebrdf design --target image:… --palette …` through the same library run
// (design_plate.h), returning arrays; with out= it writes the same run directory.
#include "design_plate.h"

#include "design.h"

#include <filesystem>

#include "wavebrdf/design_plate.h"
#include "wavebrdf/fabrication.h"

namespace wavebrdf::python {

using namespace pybind11::literals;

namespace {

py::dict design_plate(const py::object& picture, const std::string& palette, const py::object& out, bool force,
                      double plate_pixel_um, std::array<double, 2> light, int spectral, std::array<double, 2> band_um,
                      const py::object& view, double view_cone, int size, double texel_um, double height_range_um,
                      int levels, double level_step_um, const std::string& fabrication_error, std::uint64_t seed,
                      int iterations, int refine_passes, double max_memory_gb) {
    PlateOptions o;
    DesignOptions& d = o.design;
    d.omega_i = light;
    if (spectral < 1) bad_argument("spectral", std::to_string(spectral), "3 to 256 wavelengths");
    d.spectral = spectral;
    d.band_um = band_um;
    set_common_design_options(d, view, view_cone, size, texel_um, height_range_um, levels, level_step_um,
                              fabrication_error, seed, iterations, refine_passes, max_memory_gb);
    o.palette = parse_palette(palette);
    o.plate_pixel_um = plate_pixel_um;
    const long long pixel_texels = plate_pixel_texels(d, plate_pixel_um);
    const long long max_pixels = k_max_fabrication_texels / (pixel_texels * pixel_texels);
    if (py::isinstance<py::str>(picture) || py::hasattr(picture, "__fspath__")) {
        const std::string path = py::module_::import("os").attr("fspath")(picture).cast<std::string>();
        o.picture = read_plate_picture(path, max_pixels);
    } else {
        if (!py::isinstance<py::array_t<std::uint8_t>>(picture))
            bad_argument("picture", "of another type", "a PNG path or a (rows, cols, 3) uint8 array of sRGB values");
        const auto a = picture.cast<py::array_t<std::uint8_t, py::array::c_style | py::array::forcecast>>();
        if (a.ndim() != 3 || a.shape(2) != 3 || a.shape(0) < 1 || a.shape(1) < 1 || a.shape(0) > k_max_picture_side ||
            a.shape(1) > k_max_picture_side || a.shape(0) * a.shape(1) > max_pixels)
            bad_argument("picture", "of shape " + shape_string(a),
                         "(rows, cols, 3) with at most " + std::to_string(max_pixels) + " pixels for this plate");
        o.picture.rows = static_cast<int>(a.shape(0));
        o.picture.cols = static_cast<int>(a.shape(1));
        o.picture.srgb8.assign(a.data(), a.data() + a.size());
    }
    PreparedPlate prepared;
    const PlateResult r = run_design_into(
        out, force,
        [&] {
            prepared = prepare_plate(o);
            return run_plate(prepared);
        },
        [&](const std::string& dir, const PlateResult& result) { write_plate_directory(dir, result, force); });
    py::array_t<double> heights({static_cast<py::ssize_t>(r.rows), static_cast<py::ssize_t>(r.cols)});
    std::copy(r.heights_um.begin(), r.heights_um.end(), heights.mutable_data());
    const auto pr = static_cast<py::ssize_t>(r.picture_rows), pc = static_cast<py::ssize_t>(r.picture_cols);
    py::array_t<int> assignment({pr, pc});
    std::copy(prepared.assignment.begin(), prepared.assignment.end(), assignment.mutable_data());
    py::array_t<float> appearance({static_cast<py::ssize_t>(r.appearance.size()), pr, pc, py::ssize_t{3}});
    float* dst = appearance.mutable_data();
    for (const auto& panel : r.appearance) dst = std::copy(panel.begin(), panel.end(), dst);
    const py::object info = py::module_::import("json").attr("loads")(r.metrics_json);
    warn_design_warnings(info);
    return py::dict("heights_um"_a = heights, "levels_um"_a = r.levels_um, "texel_um"_a = r.texel_um,
                    "assignment"_a = assignment, "appearance"_a = appearance, "views"_a = r.view_names,
                    "design"_a = info);
}

}  // namespace

void bind_design_plate(py::module_& m) {
    m.def("design_plate", &design_plate, "picture"_a, "palette"_a, "out"_a = py::none(), "force"_a = false,
          "plate_pixel_um"_a = 0.0, "light"_a = std::array<double, 2>{{0.0, 0.0}}, "spectral"_a = 16,
          "band_um"_a = std::array<double, 2>{{0.36, 0.83}}, "view"_a = py::none(), "view_cone"_a = 0.05,
          "size"_a = 128, "texel_um"_a = 0.5, "height_range_um"_a = 2.0, "levels"_a = 16, "level_step_um"_a = 0.0,
          "fabrication_error"_a = "", "seed"_a = 1, "iterations"_a = 200, "refine_passes"_a = 60,
          "max_memory_gb"_a = 0.0,
          R"(A plate that shows a picture, one palette design per region: `wavebrdf design --target
image:PICTURE.png --palette ...` (docs/design.md, "Plate"), the same library run.

picture: a PNG path or a (rows, cols, 3) uint8 array of sRGB values. palette: '#RRGGBB;#RRGGBB;...'
or 'dir:X,Y;dir:X,Y;...'. plate_pixel_um: a picture pixel's side on the plate, a whole number of
tile periods (0: one period). The other options are the CLI's (white light: spectral >= 3; note
the defaults here: size 128, levels 16). out: also write the run directory there.

Returns a dict: heights_um (the plate, float64, um), levels_um, texel_um, assignment (each picture
pixel's palette entry), appearance (views x rows x cols x 3 float32: each region's linear sRGB into
the view cone under exact scalar diffraction of its tile), views (their names) and design (all of
design.json). The same options and seed give the same plate as the CLI.)");
}

}  // namespace wavebrdf::python
