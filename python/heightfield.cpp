// Heightfield (heightfield.h): from NumPy or an EXR file, to NumPy. Heightfield.generate and
// Heightfield.stats are generate.cpp's, read_slice io.cpp's.
#include <cstring>
#include <filesystem>
#include <optional>

#include "common.h"
#include <pybind11/stl/filesystem.h>
#include "wavebrdf/io.h"
#include "wavebrdf/surface_file.h"

namespace wavebrdf::python {

using namespace pybind11::literals;

namespace {

py::array_t<double> values_view(const Heightfield& hf, py::handle owner) {
    return readonly_view<double>(hf.values().data(), {hf.rows(), hf.cols()}, owner);
}

// Overwrites the values in place, so that views handed out earlier stay valid (they see the
// new values). Validated first: same shape, finite.
void set_values(Heightfield& hf, py::handle object) {
    const py::array a = float_array(object, "values");
    check_shape(a, {hf.rows(), hf.cols()}, "values");
    const std::vector<double> v = to_doubles(a, "values");
    std::memcpy(const_cast<double*>(hf.values().data()), v.data(), v.size() * sizeof(double));
}

py::dict attributes_dict(const HeightfieldAttributes& a) {
    py::dict d;
    d["texel_um"] = a.texel_um ? py::object(py::float_(*a.texel_um)) : py::none();
    d["vscale"] = a.vscale ? py::object(py::float_(*a.vscale)) : py::none();
    d["units"] = a.units;
    d["made_by"] = a.made_by;
    d["version"] = a.version;
    return d;
}

}  // namespace

void bind_heightfield(py::module_& m) {
    py::class_<Heightfield> cls(m, "Heightfield", R"doc(
A periodic heightfield on a grid of square texels (the public release's convention).

Values are heights in units of the texel width: the height in um is
``vscale * texel_um * value``. Row index i runs along the surface coordinate x, column j
along y; the surface tiles the plane.

Heightfield(values, texel_um=1.0, vscale=1.0)
    values    2-D float32/float64 array (rows, cols) of finite heights in texel units
              (copied once into the heightfield, as float64)
    texel_um  texel width w in um, finite and > 0
    vscale    vertical scale v (dimensionless), finite
)doc");
    cls.def(py::init([](py::handle values, double texel_um, double vscale) {
                return heightfield_from_array(values, "values", texel_um, vscale);
            }),
            "values"_a, "texel_um"_a = 1.0, "vscale"_a = 1.0)
        .def_static(
            "from_exr",
            [](const std::filesystem::path& path_arg, const py::object& texel_um, const py::object& vscale) {
                const std::string path = path_arg.string();  // str or os.PathLike (pathlib.Path)
                const HeightfieldScale scale = heightfield_file_scale(path, texel_um, vscale);
                py::gil_scoped_release release;
                return read_heightfield_exr(path, scale.texel_um, scale.vscale);
            },
            "path"_a, "texel_um"_a = py::none(), "vscale"_a = py::none(),
            "Reads the R (or Y) channel of an OpenEXR file (half or float) as heights in texel units.\n"
            "texel_um (um) and vscale: when None (default), the file's own (written by save_exr and the\n"
            "CLI), else 1.0; a given value that differs from the file's wins, with a UserWarning naming\n"
            "both. RuntimeError names the file when it is missing, unreadable or corrupt, or has a\n"
            "hostile wavebrdf attribute; ValueError on a non-finite value.")
        .def_static(
            "read",
            [](const std::filesystem::path& path_arg, const py::object& texel_um, const py::object& vscale) {
                const std::string path = path_arg.string();  // str or os.PathLike (pathlib.Path)
                const HeightfieldScale scale = heightfield_file_scale(path, texel_um, vscale);
                py::gil_scoped_release release;
                return read_heightfield_exr(path, scale.texel_um, scale.vscale);
            },
            "path"_a, "texel_um"_a = py::none(), "vscale"_a = py::none(),
            "Reads a heightfield EXR or a measured surface (x3p, sdf, Zygo .dat and .datx, sur, plu, al3d, npy,\n"
            "text matrix; recognised by content, docs/surfaces.md). A measured surface keeps its heights\n"
            "in um and is transposed so that row index i runs along x; its spacing must be square and every\n"
            "point measured (else ValueError: run `wavebrdf convert` with --resample-um / --fill). texel_um:\n"
            "the file's spacing when None; npy and text files state none and need it. vscale: 1 when None.")
        .def_static(
            "exr_attributes",
            [](const std::filesystem::path& path_arg) {
                const std::string path = path_arg.string();  // str or os.PathLike (pathlib.Path)
                HeightfieldAttributes a;
                {
                    py::gil_scoped_release release;
                    a = read_heightfield_attributes(path);
                }
                return attributes_dict(a);
            },
            "path"_a,
            "What a heightfield EXR says about itself (no pixels read): a dict with texel_um, vscale\n"
            "(None when the file does not say), units, made_by and version ('' when absent).")
        .def_property_readonly("rows", &Heightfield::rows)
        .def_property_readonly("cols", &Heightfield::cols)
        .def_property_readonly(
            "shape", [](const Heightfield& hf) { return py::make_tuple(hf.rows(), hf.cols()); }, "(rows, cols)")
        .def_property_readonly("texel_um", &Heightfield::texel_um, "texel width w in um")
        .def_property_readonly("vscale", &Heightfield::vscale, "vertical scale v")
        .def_property_readonly("period_x_um", &Heightfield::period_x_um, "tile period along x (rows), um")
        .def_property_readonly("period_y_um", &Heightfield::period_y_um, "tile period along y (columns), um")
        .def_property(
            "values", [](py::object self) { return values_view(self.cast<const Heightfield&>(), self); },
            [](Heightfield& hf, py::handle v) { set_values(hf, v); },
            "The heights in texel units, a read-only float64 view (rows, cols) of this heightfield's\n"
            "memory (no copy). Assigning an array of the same shape overwrites them in place.")
        .def(
            "to_numpy",
            [](const Heightfield& hf) {
                return owning_array(std::vector<double>(hf.values()), {hf.rows(), hf.cols()});
            },
            "A writable float64 copy of the values (rows, cols), in texel units.")
        .def(
            "__array__",
            [](py::object self, py::object dtype) {
                py::array v = values_view(self.cast<const Heightfield&>(), self);
                return dtype.is_none() ? v : py::array(v.attr("astype")(dtype));
            },
            "dtype"_a = py::none())
        .def(
            "heights_um",
            [](const Heightfield& hf) {
                std::vector<double> v = hf.values();
                for (double& x : v) x *= hf.vscale() * hf.texel_um();
                return owning_array(std::move(v), {hf.rows(), hf.cols()});
            },
            "Heights in um, vscale * texel_um * values (a new float64 array).")
        .def(
            "slope",
            [](const Heightfield& hf, int i, int j) {
                const auto s = hf.slope(i, j);
                return py::make_tuple(s[0], s[1]);
            },
            "i"_a, "j"_a, "Dimensionless slope (s_x, s_y) at texel (i, j) by periodic central differences.")
        .def(
            "with_values",
            [](const Heightfield& hf, py::handle values) {
                const py::array a = float_array(values, "values");
                check_shape(a, {hf.rows(), hf.cols()}, "values");
                return hf.with_values(to_doubles(a, "values"));
            },
            "values"_a, "The same geometry with other values (same shape).")
        .def(
            "with_scale",
            [](const Heightfield& hf, double texel_um, double vscale) {
                return hf.with_scale(check_positive(texel_um, "texel_um"), check_finite(vscale, "vscale"));
            },
            "texel_um"_a, "vscale"_a, "The same values with another texel width (um) and vertical scale.")
        .def(
            "save_exr",
            [](const Heightfield& hf, const std::filesystem::path& path_arg, const std::string& made_by) {
                const std::string path = path_arg.string();  // str or os.PathLike (pathlib.Path)
                check_output_format("path", path, {".exr"});
                py::gil_scoped_release release;
                write_heightfield_exr(path, hf, made_by);
            },
            "path"_a, "made_by"_a = "python",
            "Writes the values (texel units) as a single-channel float EXR (atomically), with the\n"
            "attributes texel_um, vscale, units, made_by and the wavebrdf version (docs/conventions.md,\n"
            "\"Files\"), so that from_exr reads the same scale back. ValueError for a path not ending in .exr.")
        .def(
            "save",
            [](const Heightfield& hf, const std::filesystem::path& path_arg, const std::string& made_by) {
                const std::string path = path_arg.string();  // str or os.PathLike (pathlib.Path)
                py::gil_scoped_release release;
                std::string ext = std::filesystem::path(path).extension().string();
                for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
                if (ext == ".exr") {
                    write_heightfield_exr(path, hf, made_by);
                } else {
                    MeasuredSurface s = from_heightfield(hf, ext.empty() ? "" : ext.substr(1));
                    s.metadata.push_back({"made_by", made_by});
                    write_surface(path, s);
                }
            },
            "path"_a, "made_by"_a = "python",
            "Writes the heightfield in the format of path's extension: .exr (save_exr), .x3p, .sdf or .npy\n"
            "(heights in um, transposed to rows along y as those formats store them; docs/surfaces.md).\n"
            "ValueError for another extension.")
        .def(
            "save_png",
            [](const Heightfield& hf, const std::filesystem::path& path_arg) {
                const std::string path = path_arg.string();  // str or os.PathLike (pathlib.Path)
                check_output_format("path", path, {".png"});
                py::gil_scoped_release release;
                write_heightfield_png(path, hf);
            },
            "path"_a, "Writes a grey PNG preview, min black, max white. ValueError for a path not ending in .png.")
        .def("copy", [](const Heightfield& hf) { return Heightfield(hf); })
        .def("__copy__", [](const Heightfield& hf) { return Heightfield(hf); })
        .def(
            "__deepcopy__", [](const Heightfield& hf, py::dict) { return Heightfield(hf); }, "memo"_a)
        .def("__repr__", [](const Heightfield& hf) {
            return "Heightfield(" + std::to_string(hf.rows()) + "x" + std::to_string(hf.cols()) +
                   ", texel_um=" + format_number(hf.texel_um()) + ", vscale=" + format_number(hf.vscale()) + ")";
        });
}

}  // namespace wavebrdf::python
