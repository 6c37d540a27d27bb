// BRDF tables (table.h): rendering one and reading its file, as dicts of NumPy arrays and
// numbers that wavebrdf/table.py wraps into a BrdfTable. This file only converts and validates.
#include "common.h"
#include "lobe.h"
#include <pybind11/stl/filesystem.h>
#include "wavebrdf/io.h"
#include "wavebrdf/table.h"

namespace wavebrdf::python {

using namespace pybind11::literals;

py::dict table_dict(BrdfTable&& t) {
    const TableSpec& s = t.spec;
    const py::ssize_t rows = s.lights.rows, cols = s.lights.cols, n = s.resolution;
    PyQuery q;
    q.query = s.query;
    q.query.omega_i = {0.0, 0.0};
    q.lambdas_um = s.lambdas_um;
    q.spectral = s.spectral;
    py::array_t<bool> rendered_array(std::vector<py::ssize_t>{rows, cols});
    for (py::ssize_t k = 0; k < rows * cols; ++k) rendered_array.mutable_data()[k] = t.rendered[std::size_t(k)] != 0;
    return py::dict("values"_a = owning_array(std::move(t.values), {rows, cols, n, n, 3}),
                    "light_x"_a = owning_array(std::move(t.light_x), {rows}),
                    "light_y"_a = owning_array(std::move(t.light_y), {cols}), "rendered"_a = rendered_array,
                    "max_light_sin"_a = s.lights.max_sin, "resolution"_a = s.resolution, "query"_a = q,
                    "lambdas_um"_a = s.lambdas_um, "spectral"_a = s.spectral,
                    "precision"_a = s.double_precision ? "double" : "float",
                    "heightfield_size"_a = py::make_tuple(t.heightfield_rows, t.heightfield_cols),
                    "texel_um"_a = t.texel_um, "vscale"_a = t.vscale, "version"_a = t.version,
                    "source"_a = t.source);
}

void bind_table(py::module_& m) {
    m.def(
        "_read_table",
        [](const std::filesystem::path& path_arg) {
            const std::string path = path_arg.string();  // str or os.PathLike (pathlib.Path)
            BrdfTable t;
            {
                py::gil_scoped_release release;
                t = read_brdf_table(path);
            }
            return table_dict(std::move(t));
        },
        "path"_a, "The table file's values and axes as a dict (wavebrdf.read_table wraps it).");
    m.def(
        "_render_table",
        [](const py::object& heightfield, const PyQuery& q, const py::object& lights, double max_light_sin,
           int resolution, const std::string& precision, double max_memory_gb, const std::string& out,
           const std::string& path, double tolerance, const py::object& comm_arg) -> py::object {
            const std::shared_ptr<const Communicator> comm = communicator_argument(comm_arg);
            const Communicator& ranks = comm ? *comm : serial_communicator();
            RenderOptions options = render_options(path, tolerance);
            // A file path: the file's own texel width and vertical scale (else 1, 1), as in the CLI.
            const Heightfield hf = [&] {
                if (!py::isinstance<py::str>(heightfield))
                    return heightfield_argument(heightfield, "heightfield", 1.0, 1.0, false);
                const std::string path = heightfield.cast<std::string>();
                py::gil_scoped_release release;
                return read_heightfield_exr(path);
            }();
            check_resolution(resolution);
            if (precision != "float" && precision != "double")
                bad_argument("precision", "'" + precision + "'", "'float' or 'double'");
            const std::array<int, 2> grid = size_argument(lights, "lights");
            TableSpec spec;
            spec.query = q.query;
            spec.lambdas_um = q.lambdas_um;
            spec.spectral = q.spectral;
            spec.resolution = resolution;
            spec.lights = {grid[0], grid[1], check_finite(max_light_sin, "max_light_sin")};
            spec.double_precision = precision == "double";
            options.max_memory_gb = max_memory_gb;
            BrdfTable t;
            {
                InterruptibleRelease release;
                t = render_brdf_table(hf, spec, options, ranks);
                if (!out.empty() && ranks.is_root()) write_brdf_table(out, t);
            }
            if (!ranks.is_root()) return py::none();  // rank 0 holds the table
            return table_dict(std::move(t));
        },
        "heightfield"_a, "query"_a, "lights"_a, "max_light_sin"_a, "resolution"_a, "precision"_a, "max_memory_gb"_a,
        "out"_a, "path"_a, "tolerance"_a, "comm"_a = py::none(),
        "render_brdf_table (and write_brdf_table when out is not empty) as a dict (wavebrdf.render_table).");
}

}  // namespace wavebrdf::python
