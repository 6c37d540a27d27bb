// HDF5 observation files (observation_file.h; the layout: docs/observations_hdf5.md), in the
// HDF5 plugin (src/plugins/hdf5_api.h), and the plugin's table (with surface_datx.cpp's reader). Serial HDF5, C API. Every file is hostile: each dataset's type class, rank and dimensions are checked
// and the memory of what will be read is bounded before anything is allocated; a failure is one
// std::runtime_error naming the file and the dataset. HDF5's own error stack printing is
// silenced while we call it, and our calls are serialised (the library may be built without
// thread safety).
#include "plugins/hdf5_api.h"

#include <sys/stat.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "wavebrdf/io.h"
#include "wavebrdf/memory.h"
#include "wavebrdf/model.h"
#include "wavebrdf/spectrum.h"
#include "wavebrdf/version.h"

#include <hdf5.h>

#include <mutex>

#include "hdf5_common.h"

namespace wavebrdf {

namespace {

using hdf5::check_storage;
using hdf5::fail;
using hdf5::Hdf5Session;
using hdf5::Id;

// The format written and read: the root attribute "wavebrdf_format".
constexpr const char* k_format = "wavebrdf_observations 1";
// Bounds of a file's dimensions, checked before allocating.
constexpr std::uint64_t k_max_observations = 100000000;  // 1e8
constexpr int k_max_wavelengths = k_max_spectral_samples;
constexpr int k_max_resolution = 8192;

// Dataset names (docs/observations_hdf5.md).
constexpr const char* k_data = "/entry_1/data_1/data";
constexpr const char* k_translation = "/entry_1/sample_1/geometry_1/translation";
constexpr const char* k_x = "/entry_1/wavebrdf_1/x_um";
constexpr const char* k_y = "/entry_1/wavebrdf_1/y_um";
constexpr const char* k_sigma = "/entry_1/wavebrdf_1/sigma_p_um";
constexpr const char* k_light = "/entry_1/wavebrdf_1/light";
constexpr const char* k_model = "/entry_1/wavebrdf_1/model";
constexpr const char* k_count = "/entry_1/wavebrdf_1/wavelength_count";
constexpr const char* k_lambdas = "/entry_1/wavebrdf_1/wavelengths_um";
// Optional: per-pixel weights, float32 [N, n, n] (absent: every pixel weighs 1).
constexpr const char* k_weights = "/entry_1/wavebrdf_1/weights";

// The core's functions (src/plugins/hdf5_api.h), given by attach.
const detail::Hdf5Host* g_host = nullptr;
const detail::Hdf5Host& host() { return *g_host; }

// ---- writing ----

void check(herr_t status, const std::string& path, const std::string& what) {
    if (status < 0) throw std::runtime_error(path + ": cannot write " + what);
}

Id checked(hid_t id, herr_t (*close)(hid_t), const std::string& path, const std::string& what) {
    if (id < 0) throw std::runtime_error(path + ": cannot create " + what);
    return Id(id, close);
}

void write_string_attribute(hid_t object, const char* name, const std::string& value, const std::string& path) {
    Id type = checked(H5Tcopy(H5T_C_S1), H5Tclose, path, "a string type");
    check(H5Tset_size(type.get(), value.size() + 1), path, name);
    check(H5Tset_strpad(type.get(), H5T_STR_NULLTERM), path, name);
    Id space = checked(H5Screate(H5S_SCALAR), H5Sclose, path, "a dataspace");
    Id attribute = checked(H5Acreate2(object, name, type.get(), space.get(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose, path,
                           name);
    check(H5Awrite(attribute.get(), type.get(), value.c_str()), path, name);
}

Id make_group(hid_t parent, const char* name, const char* nx_class, const std::string& path) {
    Id group = checked(H5Gcreate2(parent, name, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Gclose, path, name);
    write_string_attribute(group.get(), "NX_class", nx_class, path);
    return group;
}

// A dataset of `dims` holding `values` (native `memory_type`, stored as `file_type`).
template <class T>
void write_dataset(hid_t parent, const char* name, const std::vector<hsize_t>& dims, hid_t file_type, hid_t memory_type,
                   const std::vector<T>& values, const std::string& path) {
    Id space = checked(H5Screate_simple(static_cast<int>(dims.size()), dims.data(), nullptr), H5Sclose, path, name);
    Id dataset = checked(H5Dcreate2(parent, name, file_type, space.get(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT),
                         H5Dclose, path, name);
    check(H5Dwrite(dataset.get(), memory_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data()), path, name);
}

void write_file(const std::string& path, const std::string& tmp, const std::vector<Observation>& observations) {
    const std::size_t count = observations.size();
    const int n = observations.front().resolution;
    const int channels = observations.front().channels();
    std::size_t max_lambdas = 1;
    for (const Observation& o : observations) max_lambdas = std::max(max_lambdas, o.lambdas_um.size());

    Id file = checked(H5Fcreate(tmp.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT), H5Fclose, path, "the file");
    write_string_attribute(file.get(), "wavebrdf_format", k_format, path);
    write_string_attribute(file.get(), "wavebrdf_version", k_version, path);
    write_string_attribute(file.get(), "creator", std::string("wavebrdf ") + k_version, path);
    // CXI: /cxi_version (an integer) at the root.
    write_dataset(file.get(), "cxi_version", {1}, H5T_STD_I32LE, H5T_NATIVE_INT, std::vector<int>{150}, path);
    Id entry = make_group(file.get(), "entry_1", "NXentry", path);

    // The slices: N × channels × n × n float32, one chunk per observation, shuffled and deflated
    // (level 1: about 22 % smaller for 48² slices, writing and reading under 1 ms per slice).
    {
        Id data_group = make_group(entry.get(), "data_1", "NXdata", path);
        write_string_attribute(data_group.get(), "signal", "data", path);
        const hsize_t dims[4] = {count, hsize_t(channels), hsize_t(n), hsize_t(n)};
        const hsize_t chunk[4] = {1, hsize_t(channels), hsize_t(n), hsize_t(n)};
        Id space = checked(H5Screate_simple(4, dims, nullptr), H5Sclose, path, k_data);
        Id dcpl = checked(H5Pcreate(H5P_DATASET_CREATE), H5Pclose, path, k_data);
        check(H5Pset_chunk(dcpl.get(), 4, chunk), path, k_data);
        if (H5Zfilter_avail(H5Z_FILTER_DEFLATE) > 0) {
            check(H5Pset_shuffle(dcpl.get()), path, k_data);
            check(H5Pset_deflate(dcpl.get(), 1), path, k_data);
        }
        Id dataset = checked(
            H5Dcreate2(data_group.get(), "data", H5T_IEEE_F32LE, space.get(), H5P_DEFAULT, dcpl.get(), H5P_DEFAULT),
            H5Dclose, path, k_data);
        write_string_attribute(dataset.get(), "axes", "observation:channel:omega_o_x:omega_o_y", path);
        const std::size_t plane = std::size_t(n) * std::size_t(n);
        std::vector<float> slice(plane * std::size_t(channels));
        const hsize_t block[4] = {1, hsize_t(channels), hsize_t(n), hsize_t(n)};
        const hsize_t memory_dims[1] = {slice.size()};
        Id memory = checked(H5Screate_simple(1, memory_dims, nullptr), H5Sclose, path, k_data);
        for (std::size_t i = 0; i < count; ++i) {
            const std::vector<float>& r = observations[i].reference;
            // Interleaved (pixel-major, channel fastest) in memory; channel planes in the file.
            for (std::size_t p = 0; p < plane; ++p)
                for (int c = 0; c < channels; ++c) {
                    slice[std::size_t(c) * plane + p] = static_cast<float>(
                        r[p * std::size_t(channels) + std::size_t(c)]);
                }
            const hsize_t start[4] = {i, 0, 0, 0};
            check(H5Sselect_hyperslab(space.get(), H5S_SELECT_SET, start, nullptr, block, nullptr), path, k_data);
            check(H5Dwrite(dataset.get(), H5T_NATIVE_FLOAT, memory.get(), space.get(), H5P_DEFAULT, slice.data()), path,
                  k_data);
        }
        // CXI readers find the translations beside the data too.
        check(H5Lcreate_soft(k_translation, data_group.get(), "translation", H5P_DEFAULT, H5P_DEFAULT), path,
              "/entry_1/data_1/translation");
    }

    // The sample's translation (CXI: metres, x y z per frame).
    {
        Id sample = make_group(entry.get(), "sample_1", "NXsample", path);
        Id geometry = make_group(sample.get(), "geometry_1", "NXgeometry", path);
        std::vector<double> translation(3 * count);
        for (std::size_t i = 0; i < count; ++i) {
            translation[3 * i] = observations[i].query.x_um * 1e-6;
            translation[3 * i + 1] = observations[i].query.y_um * 1e-6;
            translation[3 * i + 2] = 0.0;
        }
        write_dataset(geometry.get(), "translation", {count, 3}, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, translation, path);
    }

    // The source's photon energy per frame (CXI: J) when every observation has one wavelength.
    if (channels == 1) {
        Id instrument = make_group(entry.get(), "instrument_1", "NXinstrument", path);
        Id source = make_group(instrument.get(), "source_1", "NXsource", path);
        constexpr double h = 6.62607015e-34, c = 299792458.0;
        std::vector<double> energy(count);
        for (std::size_t i = 0; i < count; ++i) energy[i] = h * c / (observations[i].lambdas_um[0] * 1e-6);
        write_dataset(source.get(), "energy", {count}, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, energy, path);
    }

    // Our exact queries and wavelengths.
    {
        Id ours = make_group(entry.get(), "wavebrdf_1", "NXcollection", path);
        std::vector<double> x(count), y(count), sigma(count), light(2 * count), lambdas(count * max_lambdas, 0.0);
        std::vector<int> model(count), lambda_count(count);
        for (std::size_t i = 0; i < count; ++i) {
            const Observation& o = observations[i];
            x[i] = o.query.x_um;
            y[i] = o.query.y_um;
            sigma[i] = o.query.sigma_p_um;
            light[2 * i] = o.query.omega_i[0];
            light[2 * i + 1] = o.query.omega_i[1];
            model[i] = static_cast<int>(o.query.model);
            lambda_count[i] = static_cast<int>(o.lambdas_um.size());
            std::copy(o.lambdas_um.begin(), o.lambdas_um.end(), lambdas.begin() + std::ptrdiff_t(i * max_lambdas));
        }
        write_dataset(ours.get(), "x_um", {count}, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, x, path);
        write_dataset(ours.get(), "y_um", {count}, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, y, path);
        write_dataset(ours.get(), "sigma_p_um", {count}, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, sigma, path);
        write_dataset(ours.get(), "light", {count, 2}, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, light, path);
        write_dataset(ours.get(), "model", {count}, H5T_STD_I32LE, H5T_NATIVE_INT, model, path);
        {
            Id dataset = checked(H5Dopen2(ours.get(), "model", H5P_DEFAULT), H5Dclose, path, k_model);
            write_string_attribute(dataset.get(), "names", "0 OHS, 1 GHS, 2 ROHS, 3 RGHS, 4 Kirchhoff", path);
        }
        write_dataset(ours.get(), "wavelength_count", {count}, H5T_STD_I32LE, H5T_NATIVE_INT, lambda_count, path);
        write_dataset(ours.get(), "wavelengths_um", {count, max_lambdas}, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, lambdas,
                      path);
        // Weights only when some observation has them (the others' pixels all weigh 1), one
        // chunk per observation like the slices.
        const bool weighted = std::any_of(observations.begin(), observations.end(),
                                          [](const Observation& o) { return !o.weights.empty(); });
        if (weighted) {
            const std::size_t plane = std::size_t(n) * std::size_t(n);
            const hsize_t dims[3] = {count, hsize_t(n), hsize_t(n)};
            const hsize_t chunk[3] = {1, hsize_t(n), hsize_t(n)};
            Id space = checked(H5Screate_simple(3, dims, nullptr), H5Sclose, path, k_weights);
            Id dcpl = checked(H5Pcreate(H5P_DATASET_CREATE), H5Pclose, path, k_weights);
            check(H5Pset_chunk(dcpl.get(), 3, chunk), path, k_weights);
            if (H5Zfilter_avail(H5Z_FILTER_DEFLATE) > 0) check(H5Pset_deflate(dcpl.get(), 1), path, k_weights);
            Id dataset = checked(
                H5Dcreate2(ours.get(), "weights", H5T_IEEE_F32LE, space.get(), H5P_DEFAULT, dcpl.get(), H5P_DEFAULT),
                H5Dclose, path, k_weights);
            const hsize_t block[3] = {1, hsize_t(n), hsize_t(n)};
            const hsize_t memory_dims[1] = {plane};
            Id memory = checked(H5Screate_simple(1, memory_dims, nullptr), H5Sclose, path, k_weights);
            const std::vector<float> ones(plane, 1.0f);
            for (std::size_t i = 0; i < count; ++i) {
                const std::vector<float>& w = observations[i].weights.empty() ? ones : observations[i].weights;
                const hsize_t start[3] = {i, 0, 0};
                check(H5Sselect_hyperslab(space.get(), H5S_SELECT_SET, start, nullptr, block, nullptr), path,
                      k_weights);
                check(H5Dwrite(dataset.get(), H5T_NATIVE_FLOAT, memory.get(), space.get(), H5P_DEFAULT, w.data()),
                      path, k_weights);
            }
        }
    }
    entry = Id();
    if (H5Fclose(file.release()) < 0) throw std::runtime_error(path + ": cannot write the file (disk full?)");
}

// ---- reading ----

// The dims of a dataset whose type class was checked.
struct Shape {
    std::vector<hsize_t> dims;
};

// Each part of `name` from the root is checked to exist and to be a hard link before the next
// is looked up, so that no lookup ever follows an external link (into another file, a FIFO, a
// device) or a soft link: a wavebrdf observation file holds its objects itself.
void check_hard_link(hid_t file, const std::string& path, const char* name, const std::string& part) {
    // H5Lexists fails (negative) when a parent group is missing: missing either way.
    if (H5Lexists(file, part.c_str(), H5P_DEFAULT) <= 0)
        fail(path, name, "missing; expected a wavebrdf observation file (docs/observations_hdf5.md)");
    H5L_info_t info{};
    if (H5Lget_info(file, part.c_str(), &info, H5P_DEFAULT) < 0) fail(path, name, "cannot read the link " + part);
    if (info.type != H5L_TYPE_HARD)
        fail(path, name,
             std::string("reaches ") + part + " through " +
                 (info.type == H5L_TYPE_EXTERNAL ? "an external link (into another file)" : "a soft or user link") +
                 "; expected objects stored in this file (links are not followed)");
}

Id open_dataset(hid_t file, const std::string& path, const char* name) {
    const std::string full(name);
    for (std::size_t at = full.find('/', 1); at != std::string::npos; at = full.find('/', at + 1))
        check_hard_link(file, path, name, full.substr(0, at));
    check_hard_link(file, path, name, full);
    const hid_t id = H5Dopen2(file, name, H5P_DEFAULT);
    if (id < 0) fail(path, name, "is not a dataset (or cannot be opened); expected a dataset");
    return Id(id, H5Dclose);
}

Shape shape_of(hid_t dataset, const std::string& path, const char* name, H5T_class_t expected_class, int rank) {
    Id type(H5Dget_type(dataset), H5Tclose);
    if (!type.valid()) fail(path, name, "cannot read its type");
    const H5T_class_t cls = H5Tget_class(type.get());
    if (cls != expected_class)
        fail(path, name,
             std::string("has the wrong type; expected ") +
                 (expected_class == H5T_FLOAT ? "floating point" : "integer"));
    const std::size_t size = H5Tget_size(type.get());
    if (size == 0 || size > 8) fail(path, name, "has a type of " + std::to_string(size) + " bytes; expected 1 to 8");
    Id space(H5Dget_space(dataset), H5Sclose);
    if (!space.valid()) fail(path, name, "cannot read its dataspace");
    const int ndims = H5Sget_simple_extent_ndims(space.get());
    if (ndims != rank || H5Sget_simple_extent_type(space.get()) != H5S_SIMPLE)
        fail(path, name, "has rank " + std::to_string(ndims) + "; expected " + std::to_string(rank));
    Shape s;
    s.dims.resize(std::size_t(rank));
    if (H5Sget_simple_extent_dims(space.get(), s.dims.data(), nullptr) != rank)
        fail(path, name, "cannot read its dims");
    return s;
}

template <class T>
std::vector<T> read_whole(hid_t dataset, hid_t memory_type, std::size_t count, const std::string& path,
                          const char* name) {
    std::vector<T> values(count);
    if (H5Dread(dataset, memory_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data()) < 0)
        fail(path, name, "cannot be read (truncated or damaged file?)");
    return values;
}

// A dataset of `dims` (checked) read whole as T.
template <class T>
std::vector<T> read_checked(hid_t file, const std::string& path, const char* name, H5T_class_t cls,
                            const std::vector<hsize_t>& dims, hid_t memory_type) {
    Id dataset = open_dataset(file, path, name);
    const Shape s = shape_of(dataset.get(), path, name, cls, static_cast<int>(dims.size()));
    std::size_t count = 1;
    for (std::size_t k = 0; k < dims.size(); ++k) {
        if (s.dims[k] != dims[k]) {
            std::string got, want;
            for (std::size_t m = 0; m < dims.size(); ++m) {
                got += (m ? " x " : "") + std::to_string(s.dims[m]);
                want += (m ? " x " : "") + std::to_string(dims[m]);
            }
            fail(path, name, "has dims " + got + "; expected " + want);
        }
        count *= std::size_t(dims[k]);
    }
    // The data must all be in this file: a few bytes may not declare gigabytes of values
    // that were never written, nor point elsewhere.
    const double chunk_bytes = check_storage(dataset.get(), path, name, dims);
    if (chunk_bytes > double(1 << 27))
        fail(path, name,
             "has chunks of " + std::to_string(static_cast<long long>(chunk_bytes / 8.0)) +
                 " values; expected at most 2^24");
    return read_whole<T>(dataset.get(), memory_type, count, path, name);
}

// A string attribute of the root (fixed or variable length, at most 256 bytes), or "" when absent.
std::string read_root_string(hid_t file, const std::string& path, const char* name) {
    if (H5Aexists(file, name) <= 0) return "";
    Id attribute(H5Aopen(file, name, H5P_DEFAULT), H5Aclose);
    if (!attribute.valid()) fail(path, name, "cannot be opened");
    Id type(H5Aget_type(attribute.get()), H5Tclose);
    Id space(H5Aget_space(attribute.get()), H5Sclose);
    if (!type.valid() || !space.valid() || H5Tget_class(type.get()) != H5T_STRING ||
        H5Sget_simple_extent_npoints(space.get()) != 1)
        fail(path, name, "attribute is not one string; expected e.g. '" + std::string(k_format) + "'");
    if (H5Tis_variable_str(type.get()) > 0) {
        // In the attribute's character set: h5py writes UTF-8, and HDF5 converts no string
        // between ASCII and UTF-8.
        Id memory(H5Tcopy(H5T_C_S1), H5Tclose);
        H5Tset_size(memory.get(), H5T_VARIABLE);
        H5Tset_cset(memory.get(), H5Tget_cset(type.get()));
        char* text = nullptr;
        if (H5Aread(attribute.get(), memory.get(), &text) < 0 || text == nullptr)
            fail(path, name, "attribute cannot be read");
        std::string value(text, std::find(text, text + 256, '\0') - text);
        H5free_memory(text);
        return value;
    }
    const std::size_t size = H5Tget_size(type.get());
    if (size == 0 || size > 256) fail(path, name, "attribute is " + std::to_string(size) + " bytes; expected ≤ 256");
    Id memory(H5Tcopy(type.get()), H5Tclose);
    std::string value(size, '\0');
    if (H5Aread(attribute.get(), memory.get(), value.data()) < 0) fail(path, name, "attribute cannot be read");
    value.erase(std::find(value.begin(), value.end(), '\0'), value.end());
    while (!value.empty() && value.back() == ' ') value.pop_back();
    return value;
}

// An open observation file: its slice dataset checked (N × channels × n × n, float, chunks
// bounded) and the index read.
struct OpenFile {
    Id file;
    Id data;
    Id data_space;
    Id weights;  // invalid when the file has none
    Id weights_space;
    ObservationIndex index;
    double chunk_bytes = 0.0;
};

OpenFile open_observation_file(const std::string& path, double max_memory_gb) {
    OpenFile f;
    // Only a regular file (after links): a FIFO would block H5Fopen forever (the core's
    // check_readable_file, which this plugin does not link).
    {
        struct stat st {};
        if (::stat(path.c_str(), &st) == 0 && !S_ISREG(st.st_mode))
            throw std::runtime_error(path + ": is " +
                                     (S_ISFIFO(st.st_mode)  ? "a FIFO"
                                      : S_ISDIR(st.st_mode) ? "a directory"
                                      : S_ISCHR(st.st_mode) ? "a character device"
                                                            : "a special file") +
                                     ", not a regular file; expected a regular file to read");
    }
    // Read-only and without file locks: the ranks of a run open one file at once, on file
    // systems (NFS, Lustre) where flock may fail; our writer renames complete files into
    // place, so no reader ever sees one being written.
    Id fapl(H5Pcreate(H5P_FILE_ACCESS), H5Pclose);
    if (!fapl.valid()) throw std::runtime_error(path + ": cannot open it (HDF5 property list)");
#if H5_VERSION_GE(1, 10, 7)
    H5Pset_file_locking(fapl.get(), 0, 1);
#endif
    const hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDONLY, fapl.get());
    if (file < 0) throw std::runtime_error(path + ": cannot open it as HDF5 (missing, not HDF5, or truncated)");
    f.file = Id(file, H5Fclose);
    const std::string format = read_root_string(file, path, "wavebrdf_format");
    if (format != k_format)
        fail(path, "/ attribute wavebrdf_format",
             format.empty() ? "missing; expected '" + std::string(k_format) + "' (a file written by wavebrdf)"
                            : "is '" + format + "'; this build reads '" + std::string(k_format) + "'");

    f.data = open_dataset(file, path, k_data);
    const Shape s = shape_of(f.data.get(), path, k_data, H5T_FLOAT, 4);
    const hsize_t count = s.dims[0], channels = s.dims[1], n = s.dims[2];
    if (count < 1 || count > k_max_observations)
        fail(path, k_data, "holds " + std::to_string(count) + " observations; expected 1 to 1e8");
    if (channels != 1 && channels != 3)
        fail(path, k_data, "has " + std::to_string(channels) + " channels; expected 1 or 3");
    if (n < 1 || n > hsize_t(k_max_resolution) || s.dims[3] != n)
        fail(path, k_data,
             "slices are " + std::to_string(n) + " x " + std::to_string(s.dims[3]) + "; expected n x n, 1 ≤ n ≤ 8192");
    f.data_space = Id(H5Dget_space(f.data.get()), H5Sclose);
    // The index: bounded by the count, the wavelengths' dims checked first.
    const std::size_t N = std::size_t(count);
    Id lambdas_dataset = open_dataset(file, path, k_lambdas);
    const Shape ls = shape_of(lambdas_dataset.get(), path, k_lambdas, H5T_FLOAT, 2);
    lambdas_dataset = Id();
    if (ls.dims[0] != count || ls.dims[1] < 1 || ls.dims[1] > hsize_t(k_max_wavelengths))
        fail(path, k_lambdas,
             "has dims " + std::to_string(ls.dims[0]) + " x " + std::to_string(ls.dims[1]) + "; expected " +
                 std::to_string(count) + " x (1 to " + std::to_string(k_max_wavelengths) + ")");
    const std::size_t L = std::size_t(ls.dims[1]);
    host().require_memory(double(N) * (8.0 * double(6 + 2 * L) + double(sizeof(Query)) + 64.0), max_memory_gb,
                   "reading the index of the " + std::to_string(N) + " observations of " + path);
    const auto x = read_checked<double>(file, path, k_x, H5T_FLOAT, {count}, H5T_NATIVE_DOUBLE);
    const auto y = read_checked<double>(file, path, k_y, H5T_FLOAT, {count}, H5T_NATIVE_DOUBLE);
    const auto sigma = read_checked<double>(file, path, k_sigma, H5T_FLOAT, {count}, H5T_NATIVE_DOUBLE);
    const auto light = read_checked<double>(file, path, k_light, H5T_FLOAT, {count, 2}, H5T_NATIVE_DOUBLE);
    const auto model = read_checked<int>(file, path, k_model, H5T_INTEGER, {count}, H5T_NATIVE_INT);
    const auto lambda_count = read_checked<int>(file, path, k_count, H5T_INTEGER, {count}, H5T_NATIVE_INT);
    const auto lambdas = read_checked<double>(file, path, k_lambdas, H5T_FLOAT, {count, hsize_t(L)}, H5T_NATIVE_DOUBLE);

    // Where the slices are, checked before any of them is read (after the index, whose memory
    // bound and storage come first); chunks are read whole: bound them (a slice, or 2^24 values).
    f.chunk_bytes = check_storage(f.data.get(), path, k_data, s.dims);
    {
        const double elements = f.chunk_bytes / 8.0;
        const double slice = double(channels) * double(n) * double(n);
        if (elements > std::max(slice, double(1 << 24)))
            fail(path, k_data,
                 "has chunks of " + std::to_string(static_cast<long long>(elements)) +
                     " values; expected at most one slice or 2^24");
    }

    // The optional weights: [N, n, n] float, stored in this file, chunks of at most one plane.
    // (Its parents were checked as hard links above; H5Lexists does not follow the last link.)
    if (H5Lexists(file, k_weights, H5P_DEFAULT) > 0) {
        f.weights = open_dataset(file, path, k_weights);
        const Shape ws = shape_of(f.weights.get(), path, k_weights, H5T_FLOAT, 3);
        if (ws.dims[0] != count || ws.dims[1] != n || ws.dims[2] != n)
            fail(path, k_weights,
                 "has dims " + std::to_string(ws.dims[0]) + " x " + std::to_string(ws.dims[1]) + " x " +
                     std::to_string(ws.dims[2]) + "; expected " + std::to_string(count) + " x " + std::to_string(n) +
                     " x " + std::to_string(n) + " (one weight per slice pixel)");
        const double elements = check_storage(f.weights.get(), path, k_weights, ws.dims) / 8.0;
        if (elements > std::max(double(n) * double(n), double(1 << 24)))
            fail(path, k_weights,
                 "has chunks of " + std::to_string(static_cast<long long>(elements)) +
                     " values; expected at most one plane or 2^24");
        f.chunk_bytes = std::max(f.chunk_bytes, elements * 8.0);
        f.weights_space = Id(H5Dget_space(f.weights.get()), H5Sclose);
    }

    ObservationIndex& index = f.index;
    index.resolution = static_cast<int>(n);
    index.channels = static_cast<int>(channels);
    index.queries.resize(N);
    index.lambdas_um.resize(N);
    for (std::size_t i = 0; i < N; ++i) {
        const std::string at = "observation " + std::to_string(i) + ": ";
        Query& q = index.queries[i];
        q.x_um = x[i];
        q.y_um = y[i];
        q.sigma_p_um = sigma[i];
        q.omega_i = {light[2 * i], light[2 * i + 1]};
        if (model[i] < 0 || model[i] > static_cast<int>(Model::Kirchhoff))
            fail(path, k_model, at + "code " + std::to_string(model[i]) + " is unknown; expected 0 to 4");
        q.model = static_cast<Model>(model[i]);
        const int k = lambda_count[i];
        if (k < 1 || k > static_cast<int>(L))
            fail(path, k_count, at + std::to_string(k) + " wavelengths; expected 1 to " + std::to_string(L));
        if ((k == 1) != (channels == 1))
            fail(path, k_count,
                 at + std::to_string(k) + " wavelength(s) with " + std::to_string(channels) +
                     " channel(s); expected 1 wavelength for 1 channel, several for 3");
        index.lambdas_um[i].assign(lambdas.begin() + std::ptrdiff_t(i * L),
                                   lambdas.begin() + std::ptrdiff_t(i * L + std::size_t(k)));
        try {
            host().validate_query(q);
            for (double l : index.lambdas_um[i]) host().validate_lambda(l);
        } catch (const std::exception& e) {
            fail(path, "/entry_1/wavebrdf_1", at + e.what());
        }
    }
    return f;
}

void plugin_write_observations(const std::string& path, const std::vector<Observation>& observations) {
    if (observations.empty())
        throw std::invalid_argument("no observations to write to " + path + "; expected at least one");
    for (std::size_t i = 0; i < observations.size(); ++i) {
        host().validate_observation(observations[i], i);
        const Observation& o = observations[i];
        const Observation& first = observations.front();
        if (o.resolution != first.resolution || o.channels() != first.channels())
            throw std::invalid_argument(
                "observation " + std::to_string(i) + " has resolution " + std::to_string(o.resolution) + " and " +
                std::to_string(o.channels()) + " channel(s), observation 0 " + std::to_string(first.resolution) +
                " and " + std::to_string(first.channels()) +
                "; an HDF5 observation file holds one resolution and channel count (use JSON for mixed sets)");
    }
    host().write_file_atomically(path, [&](const std::string& tmp) {
        const Hdf5Session session;
        write_file(path, tmp, observations);
    });
}

ObservationIndex plugin_read_observation_index(const std::string& path, double max_memory_gb) {
    const Hdf5Session session;
    return open_observation_file(path, max_memory_gb).index;
}

std::vector<Observation> plugin_read_observations(const std::string& path, const std::vector<std::size_t>& indices,
                                                double max_memory_gb) {
    const Hdf5Session session;
    OpenFile f = open_observation_file(path, max_memory_gb);
    const ObservationIndex& index = f.index;
    for (std::size_t i : indices)
        if (i >= index.size())
            throw std::out_of_range(path + ": observation index " + std::to_string(i) +
                                    " is out of range; the file holds " + std::to_string(index.size()));
    const std::size_t n = std::size_t(index.resolution), channels = std::size_t(index.channels);
    const std::size_t values = n * n * channels;
    host().require_memory(double(indices.size()) * double(values + (f.weights.valid() ? n * n : 0)) * 8.0 +
                              double(values) * 4.0 + f.chunk_bytes,
                          max_memory_gb,
                   "reading " + std::to_string(indices.size()) + " observations of " + path);

    std::vector<Observation> out;
    out.reserve(indices.size());
    std::vector<float> slice(values);
    const hsize_t memory_dims[1] = {values};
    Id memory(H5Screate_simple(1, memory_dims, nullptr), H5Sclose);
    const hsize_t block[4] = {1, channels, n, n};
    const std::size_t plane = n * n;
    for (std::size_t i : indices) {
        const hsize_t start[4] = {i, 0, 0, 0};
        if (H5Sselect_hyperslab(f.data_space.get(), H5S_SELECT_SET, start, nullptr, block, nullptr) < 0 ||
            H5Dread(f.data.get(), H5T_NATIVE_FLOAT, memory.get(), f.data_space.get(), H5P_DEFAULT, slice.data()) < 0)
            fail(path, k_data, "observation " + std::to_string(i) + " cannot be read (truncated or damaged file?)");
        Observation o;
        o.query = index.queries[i];
        o.lambdas_um = index.lambdas_um[i];
        o.resolution = index.resolution;
        o.reference.resize(values);
        for (std::size_t p = 0; p < plane; ++p)
            for (std::size_t c = 0; c < channels; ++c) o.reference[p * channels + c] = slice[c * plane + p];
        if (f.weights.valid()) {
            o.weights.resize(plane);
            const hsize_t wstart[3] = {i, 0, 0}, wblock[3] = {1, n, n};
            const hsize_t wdims[1] = {plane};
            Id wmemory(H5Screate_simple(1, wdims, nullptr), H5Sclose);
            if (H5Sselect_hyperslab(f.weights_space.get(), H5S_SELECT_SET, wstart, nullptr, wblock, nullptr) < 0 ||
                H5Dread(f.weights.get(), H5T_NATIVE_FLOAT, wmemory.get(), f.weights_space.get(), H5P_DEFAULT,
                        o.weights.data()) < 0)
                fail(path, k_weights,
                     "observation " + std::to_string(i) + " cannot be read (truncated or damaged file?)");
        }
        try {
            host().validate_observation(o, i);
        } catch (const std::exception& e) {
            fail(path, k_data, e.what());
        }
        out.push_back(std::move(o));
    }
    return out;
}

void attach(const detail::Hdf5Host* h) { g_host = h; }

const detail::Hdf5Api k_api = {
    detail::k_hdf5_api_version, attach, plugin_write_observations, plugin_read_observation_index,
    plugin_read_observations, hdf5::read_datx,
};

}  // namespace

}  // namespace wavebrdf

extern "C" __attribute__((visibility("default"))) const wavebrdf::detail::Hdf5Api* wavebrdf_hdf5_api() {
    return &wavebrdf::k_api;
}
