// Observation files (observation_file.h): read_observations, read_observation_index,
// built_with_hdf5, write_observations.
#include <pybind11/stl/filesystem.h>

#include "common.h"
#include "observation_arg.h"
#include "wavebrdf/observation_file.h"

namespace wavebrdf::python {

using namespace pybind11::literals;

void bind_observation_file(py::module_& m) {
    m.def(
        "read_observations",
        [](const std::filesystem::path& path_arg, const py::object& indices, int rank, int size, double max_memory_gb) {
            const std::string path = path_arg.string();  // str or os.PathLike (pathlib.Path)
            if (!indices.is_none() && size != 1)
                throw py::value_error("indices and rank/size exclude each other; give one of them");
            if (indices.is_none()) {
                py::gil_scoped_release release;
                return read_observations_file(path, rank, size, max_memory_gb);
            }
            std::vector<std::size_t> list;
            try {
                list = indices.cast<std::vector<std::size_t>>();
            } catch (const py::cast_error&) {
                throw py::value_error("indices = " + std::string(py::repr(indices)) +
                                      " is invalid; expected a list of non-negative integers");
            }
            py::gil_scoped_release release;
            if (is_hdf5_file(path)) return read_observations_hdf5(path, list, max_memory_gb);
            // JSON: read whole, the indices picked.
            std::vector<Observation> all = read_observations_json(path, max_memory_gb), out;
            for (std::size_t i : list) {
                if (i >= all.size())
                    throw std::out_of_range(path + ": observation index " + std::to_string(i) +
                                            " is out of range; the file holds " + std::to_string(all.size()));
                out.push_back(all[i]);
            }
            return out;
        },
        "path"_a, "indices"_a = py::none(), py::kw_only(), "rank"_a = 0, "size"_a = 1, "max_memory_gb"_a = 0.0, R"doc(
Observations from a file (what `wavebrdf invert|recover --observations` read): HDF5 (.h5,
.hdf5, .cxi, or any file with the HDF5 signature; docs/observations_hdf5.md) or JSON.
indices        positions in an HDF5 file to read (only their slices are read), in the order
               given; None: all
rank, size     only the observations rank `rank` of `size` holds (split by footprint position,
               as the MPI runs split them: wavebrdf.observation_share), in file order
max_memory_gb  refuse (MemoryError) a read needing more than this many GB (0: physical memory)
)doc");
    m.def(
        "read_observation_index",
        [](const std::filesystem::path& path_arg, double max_memory_gb) {
            const std::string path = path_arg.string();  // str or os.PathLike (pathlib.Path)
            ObservationIndex index;
            {
                py::gil_scoped_release release;
                index = read_observation_index(path, max_memory_gb);
            }
            py::list queries;
            std::vector<double> positions(2 * index.size());
            for (std::size_t i = 0; i < index.size(); ++i) {
                PyQuery q;
                q.query = index.queries[i];
                q.lambdas_um = index.lambdas_um[i];
                q.spectral = q.lambdas_um.size() > 1;
                queries.append(py::cast(q));
                positions[2 * i] = index.queries[i].x_um;
                positions[2 * i + 1] = index.queries[i].y_um;
            }
            py::dict out;
            out["queries"] = queries;
            out["positions_um"] = owning_array(std::move(positions), {py::ssize_t(index.size()), 2});
            out["resolution"] = index.resolution;
            out["channels"] = index.channels;
            return out;
        },
        "path"_a, "max_memory_gb"_a = 0.0, R"doc(
What an observation file holds, without its slices: a dict with 'queries' (a Query per
observation, with its wavelengths), 'positions_um' (float64 (N, 2): x_um, y_um), 'resolution'
and 'channels' (1 or 3). An HDF5 file reads its metadata only; a JSON file is read whole.
)doc");
    m.def("built_with_hdf5", &built_with_hdf5,
          "Whether this build reads and writes HDF5 observation files (CMake option WAVEBRDF_HDF5).");
    m.def(
        "write_observations",
        [](const std::filesystem::path& path_arg, const py::object& observations, const std::string& references) {
            const std::string path = path_arg.string();  // str or os.PathLike (pathlib.Path)
            ReferenceStorage storage = ReferenceStorage::Inline;
            if (references == "exr")
                storage = ReferenceStorage::Exr;
            else if (references != "inline")
                bad_argument("references", "'" + references + "'", "'inline' or 'exr'");
            const std::vector<Observation> list = observations_argument(observations);
            py::gil_scoped_release release;
            write_observations_file(path, list, storage);
        },
        "path"_a, "observations"_a, "references"_a = "inline", R"doc(
Writes observations (the formats read_observations and `wavebrdf invert|recover
--observations` read), atomically: one HDF5 file for a path ending in .h5, .hdf5 or .cxi
(slices as float32, one resolution and channel count for all; docs/observations_hdf5.md),
else JSON. references (JSON only): 'inline' (values in the JSON, exact) or 'exr' (float EXR
files NAME/slice_0000.exr ... beside the JSON, NAME its file name without the extension: what
`wavebrdf recover --save-observations` writes).
)doc");
}

}  // namespace wavebrdf::python
