// Fabrication exports (fabrication.h): heights.png, the lithography masks and heights.stl of a
// relief given as a 2-D array of heights in µm. This file only converts and validates.
#include "fabrication.h"

#include "wavebrdf/fabrication.h"

namespace wavebrdf::python {

using namespace pybind11::literals;

void bind_fabrication(py::module_& m) {
    m.def(
        "write_fabrication_exports",
        [](const std::string& out_dir, const py::object& heights_um, double texel_um, double height_range_um,
           int levels, double max_stl_gb) {
            const py::array a = float_array(heights_um, "heights_um");
            if (a.ndim() != 2) bad_argument("heights_um", std::to_string(a.ndim()) + "-D array", "a 2-D array (rows, cols)");
            const long long rows = a.shape(0), cols = a.shape(1);
            if (rows < 1 || cols < 1 || rows * cols > k_max_fabrication_texels)
                bad_argument("heights_um", std::to_string(rows) + " x " + std::to_string(cols),
                             "1 ... " + std::to_string(k_max_fabrication_texels) + " texels");
            const std::vector<double> heights = to_doubles(a, "heights_um");
            FabricationFiles files;
            {
                py::gil_scoped_release release;
                files = write_fabrication_exports(out_dir, heights, static_cast<int>(rows), static_cast<int>(cols),
                                                  texel_um, height_range_um, levels, check_finite(max_stl_gb, "max_stl_gb") * 1e9);
            }
            py::list masks;
            for (const LevelMask& mask : files.masks)
                masks.append(py::dict("path"_a = mask.path, "depth_um"_a = mask.depth_um, "weight"_a = mask.weight));
            return py::dict("heights_png"_a = files.heights_png, "heights_stl"_a = files.heights_stl,
                            "masks_json"_a = files.masks_json, "masks"_a = masks,
                            "stl_triangles"_a = files.stl_triangles, "note"_a = files.note,
                            "heights_x3p"_a = files.heights_x3p, "x3p_note"_a = files.x3p_note);
        },
        "out_dir"_a, "heights_um"_a, "texel_um"_a, "height_range_um"_a, "levels"_a = 0, "max_stl_gb"_a = 4.0,
        R"doc(
Writes the fabrication files of a relief of square texels (docs/fabrication.md) into the
existing directory out_dir: heights.png (16-bit grey, 0...height_range_um, the scale in text
chunks), heights.stl (a closed binary STL solid in um; skipped beyond max_stl_gb, with a note),
heights.x3p (ISO 25178-72, float64 um; skipped with x3p_note when the x3p plugin does not load or
its copies, 24 bytes a texel, exceed max_stl_gb) and, when levels > 0, masks_01.png ... and masks.json (the masks of multi-step lithography:
log2 K binary-weighted masks when K is a power of two, else K - 1 cumulative ones; each height
must then be a level k * height_range_um / (levels - 1)).

heights_um: 2-D array (rows, cols) of heights in um, within 0...height_range_um; texel_um:
texel width in um. Returns a dict: heights_png, heights_stl ('' when skipped), masks_json,
masks (list of {path, depth_um, weight}), stl_triangles, note, heights_x3p ('' when skipped),
x3p_note. ValueError for a bad value
(naming the texel), RuntimeError when a file cannot be written.)doc");
}

}  // namespace wavebrdf::python
