// Slice files (io.h): read_slice.
#include <filesystem>

#include "common.h"
#include <pybind11/stl/filesystem.h>
#include "wavebrdf/io.h"

namespace wavebrdf::python {

using namespace pybind11::literals;

void bind_io(py::module_& m) {
    m.def(
        "read_slice",
        [](const std::filesystem::path& path_arg) {
            const std::string path = path_arg.string();  // str or os.PathLike (pathlib.Path)
            SliceFile file;
            {
                py::gil_scoped_release release;
                file = read_slice_exr(path);
            }
            const py::ssize_t rows = file.image.rows, cols = file.image.cols;
            py::array_t<float> image = owning_array(std::move(file.image.data), {rows, cols, 3});
            py::dict d;
            if (file.attributes) {
                const SliceAttributes& a = *file.attributes;
                d["x_um"] = a.query.x_um;
                d["y_um"] = a.query.y_um;
                d["sigma_p_um"] = a.query.sigma_p_um;
                d["light"] = py::make_tuple(a.query.omega_i[0], a.query.omega_i[1]);
                d["model"] = std::string(to_string(a.query.model));
                d["lambdas_um"] = a.lambdas_um;
                d["resolution"] = a.resolution;
                d["channels"] = a.channels;
                if (a.heightfield_rows > 0) {
                    d["texel_um"] = a.texel_um;
                    d["vscale"] = a.vscale;
                    d["heightfield_size"] = py::make_tuple(a.heightfield_rows, a.heightfield_cols);
                    d["heightfield_file"] = a.heightfield_file;
                }
                d["unit"] = a.unit;
                d["made_by"] = a.made_by;
                d["version"] = a.version;
            }
            return py::make_tuple(image, d);
        },
        "path"_a, R"doc(
Reads a slice EXR written by wavebrdf (render --out, genbrdf -o, a run's reference_/final_
slices, observation files) or any RGB EXR.

Returns (image, info): image a float32 array (n, n, 3), linear, in the slice's unit; info a dict
of what the file says about itself: x_um, y_um, sigma_p_um (um), light (omega_i x, y), model,
lambdas_um (list, um), resolution, channels (1: one wavelength, stored R = G = B; 3: sRGB),
the heightfield's texel_um, vscale, heightfield_size (rows, cols) and heightfield_file (when
known), unit (f_r, the BRDF, in 1/sr), made_by and version. An empty dict for a file without
wavebrdf's attributes. RuntimeError names the file when it is unreadable or an attribute is
hostile.)doc");
}

}  // namespace wavebrdf::python
