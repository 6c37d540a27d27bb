// Zygo .datx files (HDF5; Zygo's Mx and MetroPro write them): the measurement's height map, in
// the HDF5 plugin (src/plugins/hdf5_api.h). The layout read (docs/surfaces.md, "Zygo datx"):
// the group /Data/Surface holds one dataset, rows × columns of float32 or float64 values, rows
// along y and x fastest; its attributes
//   "Z Converter"  compound {Category, BaseUnit: strings; Parameters: doubles}: "HeightCat" with
//                  BaseUnit "Fringes": height = value · P[1] · P[2] · P[3] metres (wavelength,
//                  interferometric scale factor, obliquity factor), or a length unit by name
//   "X Converter", "Y Converter"  "LateralCat" with BaseUnit "Pixels": spacing P[1] metres
//   "No Data"      the value that marks a point not measured
// The file is hostile: it is opened from memory (HDF5's core driver with a file image: no other
// file is touched), no soft or external link is followed, the dataset's type, rank and size are
// bounded (surface_file.h) and its storage checked (hdf5_common.h) before it is read, and every
// failure is one std::runtime_error naming the file.
#include <hdf5.h>

#include <cmath>
#include <cstddef>
#include <cstdio>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "hdf5_common.h"
#include "plugins/hdf5_api.h"

namespace wavebrdf::hdf5 {

namespace {

constexpr const char* k_surface_group = "/Data/Surface";

[[noreturn]] void refuse(const std::string& name, const std::string& what) {
    throw std::runtime_error(name + ": " + what);
}

// `part` (an absolute path) exists and is a hard link: no lookup follows a link elsewhere.
void require_hard_link(hid_t file, const std::string& name, const std::string& part) {
    if (H5Lexists(file, part.c_str(), H5P_DEFAULT) <= 0)
        refuse(name, "has no " + part + "; expected a Zygo datx file (an HDF5 file with the surface in " +
                         std::string(k_surface_group) + ")");
    H5L_info_t info{};
    if (H5Lget_info(file, part.c_str(), &info, H5P_DEFAULT) < 0) refuse(name, "cannot read the link " + part);
    if (info.type != H5L_TYPE_HARD)
        refuse(name, part + " is " +
                         (info.type == H5L_TYPE_EXTERNAL ? std::string("an external link (into another file)")
                                                         : std::string("a soft or user link")) +
                         "; expected objects stored in this file (links are not followed)");
}

// One attribute's element count (its dataspace), or -1 when it has none.
long long attribute_points(hid_t attribute) {
    Id space(H5Aget_space(attribute), H5Sclose);
    if (!space.valid()) return -1;
    return static_cast<long long>(H5Sget_simple_extent_npoints(space.get()));
}

struct Converter {
    std::string category, base_unit;
    std::vector<double> parameters;
};

// The converter attribute `key` of `dataset` (one element of {string, string, vlen double}).
Converter read_converter(hid_t dataset, const char* key, const std::string& name, const std::string& where) {
    if (H5Aexists(dataset, key) <= 0)
        refuse(name, where + " has no attribute '" + key + "'; expected a Zygo datx surface");
    Id attribute(H5Aopen(dataset, key, H5P_DEFAULT), H5Aclose);
    if (!attribute.valid()) refuse(name, where + ": attribute '" + key + "' cannot be opened");
    if (attribute_points(attribute.get()) != 1)
        refuse(name, where + ": attribute '" + key + "' holds " + std::to_string(attribute_points(attribute.get())) +
                         " elements; expected one converter");
    Id file_type(H5Aget_type(attribute.get()), H5Tclose);
    if (!file_type.valid() || H5Tget_class(file_type.get()) != H5T_COMPOUND)
        refuse(name, where + ": attribute '" + key + "' is not a compound; expected {Category, BaseUnit, Parameters}");
    struct Raw {
        char* category;
        char* base_unit;
        hvl_t parameters;
    };
    // Variable-length strings in the file's character set (Zygo writes ASCII, h5py UTF-8): HDF5
    // converts no string from one set to the other.
    const auto text_type = [&](const char* member) {
        H5T_cset_t cset = H5T_CSET_ASCII;
        const int index = H5Tget_member_index(file_type.get(), member);
        if (index >= 0) {
            Id t(H5Tget_member_type(file_type.get(), unsigned(index)), H5Tclose);
            if (t.valid() && H5Tget_class(t.get()) == H5T_STRING) {
                const H5T_cset_t c = H5Tget_cset(t.get());
                if (c == H5T_CSET_UTF8) cset = c;
            }
        }
        Id text(H5Tcopy(H5T_C_S1), H5Tclose);
        if (text.valid()) {
            H5Tset_size(text.get(), H5T_VARIABLE);
            H5Tset_cset(text.get(), cset);
        }
        return text;
    };
    const Id category_text = text_type("Category"), unit_text = text_type("BaseUnit");
    Id doubles(H5Tvlen_create(H5T_NATIVE_DOUBLE), H5Tclose);
    Id memory(H5Tcreate(H5T_COMPOUND, sizeof(Raw)), H5Tclose);
    if (!category_text.valid() || !unit_text.valid() || !doubles.valid() || !memory.valid() ||
        H5Tinsert(memory.get(), "Category", offsetof(Raw, category), category_text.get()) < 0 ||
        H5Tinsert(memory.get(), "BaseUnit", offsetof(Raw, base_unit), unit_text.get()) < 0 ||
        H5Tinsert(memory.get(), "Parameters", offsetof(Raw, parameters), doubles.get()) < 0)
        refuse(name, "cannot read the datx converters (HDF5 types)");
    Raw raw{};
    if (H5Aread(attribute.get(), memory.get(), &raw) < 0)
        refuse(name, where + ": attribute '" + key +
                         "' cannot be read as {Category, BaseUnit: strings, Parameters: doubles}");
    Converter c;
    if (raw.category != nullptr) c.category = raw.category;
    if (raw.base_unit != nullptr) c.base_unit = raw.base_unit;
    // HDF5 allocated the parameters from the file's own bytes (a global heap object), so their
    // count is bounded by the file's size.
    if (raw.parameters.p != nullptr)
        c.parameters.assign(static_cast<const double*>(raw.parameters.p),
                            static_cast<const double*>(raw.parameters.p) + raw.parameters.len);
    Id scalar(H5Screate(H5S_SCALAR), H5Sclose);
#if H5_VERSION_GE(1, 12, 0)
    H5Treclaim(memory.get(), scalar.get(), H5P_DEFAULT, &raw);
#else
    H5Dvlen_reclaim(memory.get(), scalar.get(), H5P_DEFAULT, &raw);
#endif
    return c;
}

std::string number(double v) {
    char text[32];
    std::snprintf(text, sizeof text, "%.17g", v);
    return text;
}

// Parameter `k` of a converter, finite and > 0.
double parameter(const Converter& c, std::size_t k, const std::string& name, const std::string& what) {
    if (c.parameters.size() <= k || !std::isfinite(c.parameters[k]) || !(c.parameters[k] > 0.0))
        refuse(name, what + " (converter parameter " + std::to_string(k) + ") is " +
                         (c.parameters.size() <= k ? std::string("missing") : number(c.parameters[k])) +
                         "; expected a finite value > 0");
    return c.parameters[k];
}

// Micrometres per unit of a length unit named as Zygo's converters name them; 0 when unknown.
double micrometres_per(const std::string& unit) {
    const std::pair<const char*, double> units[] = {{"Meters", 1e6},      {"MilliMeters", 1e3}, {"Millimeters", 1e3},
                                                    {"MicroMeters", 1.0}, {"Micrometers", 1.0}, {"NanoMeters", 1e-3},
                                                    {"Nanometers", 1e-3}, {"Angstroms", 1e-4}};
    for (const auto& u : units)
        if (unit == u.first) return u.second;
    return 0.0;
}

// The lateral spacing in µm from an "X Converter" / "Y Converter".
double spacing_um(const Converter& c, const std::string& name, const std::string& axis) {
    if (c.category != "LateralCat" || c.base_unit != "Pixels")
        refuse(name, axis + " Converter is '" + c.category + "' in '" + c.base_unit +
                         "'; expected 'LateralCat' in 'Pixels' (the spacing in metres per pixel)");
    return parameter(c, 1, name, axis + " spacing (m per pixel)") * 1e6;
}

MeasuredSurface read(const std::string& data, const std::string& name) {
    Hdf5Session session;
    Id fapl(H5Pcreate(H5P_FILE_ACCESS), H5Pclose);
    // The bytes as an in-memory file (copied by HDF5); nothing is read from or written to disk.
    if (!fapl.valid() || H5Pset_fapl_core(fapl.get(), 1 << 16, 0) < 0 ||
        H5Pset_file_image(fapl.get(), const_cast<char*>(data.data()), data.size()) < 0)
        refuse(name, "cannot be opened as HDF5 (file image)");
    // The core driver refuses an image whose name exists on disk ("file already exists") and
    // probes the name with open(2): a name that cannot exist (a path under /dev/null).
    Id file(H5Fopen("/dev/null/wavebrdf-datx-in-memory", H5F_ACC_RDONLY, fapl.get()), H5Fclose);
    if (!file.valid()) refuse(name, "cannot be opened as HDF5 (truncated or damaged)");
    require_hard_link(file.get(), name, "/Data");
    require_hard_link(file.get(), name, k_surface_group);
    Id group(H5Gopen2(file.get(), k_surface_group, H5P_DEFAULT), H5Gclose);
    if (!group.valid()) refuse(name, std::string(k_surface_group) + " is not a group; expected a Zygo datx file");
    H5G_info_t info{};
    if (H5Gget_info(group.get(), &info) < 0) refuse(name, "cannot list " + std::string(k_surface_group));
    if (info.nlinks != 1)
        refuse(name, std::string(k_surface_group) + " holds " + std::to_string(info.nlinks) +
                         " objects; expected one surface (files of several are not read)");
    char member[256] = {};
    const ssize_t length = H5Lget_name_by_idx(group.get(), ".", H5_INDEX_NAME, H5_ITER_INC, 0, member, sizeof member,
                                              H5P_DEFAULT);
    if (length <= 0 || length >= static_cast<ssize_t>(sizeof member))
        refuse(name,
               "the surface's name in " + std::string(k_surface_group) + " cannot be read (or is over 255 bytes)");
    const std::string where = std::string(k_surface_group) + "/" + member;
    require_hard_link(file.get(), name, where);
    Id dataset(H5Dopen2(file.get(), where.c_str(), H5P_DEFAULT), H5Dclose);
    if (!dataset.valid()) refuse(name, where + " is not a dataset; expected the height map");

    Id type(H5Dget_type(dataset.get()), H5Tclose);
    if (!type.valid()) refuse(name, where + ": cannot read its type");
    const std::size_t value_bytes = H5Tget_size(type.get());
    if (H5Tget_class(type.get()) != H5T_FLOAT || (value_bytes != 4 && value_bytes != 8))
        refuse(name, where + " is not float32 or float64; expected the heights as floating point");
    Id space(H5Dget_space(dataset.get()), H5Sclose);
    if (!space.valid() || H5Sget_simple_extent_type(space.get()) != H5S_SIMPLE ||
        H5Sget_simple_extent_ndims(space.get()) != 2)
        refuse(name, where + " is not two-dimensional; expected rows x columns of heights");
    hsize_t dims[2] = {0, 0};
    H5Sget_simple_extent_dims(space.get(), dims, nullptr);
    // Bounded before anything is allocated (the sides and points every reader allows).
    if (dims[0] < 1 || dims[1] < 1 || dims[0] > hsize_t(k_max_surface_side) || dims[1] > hsize_t(k_max_surface_side) ||
        double(dims[0]) * double(dims[1]) > double(k_max_surface_points))
        refuse(name, where + " is " + std::to_string(dims[1]) + " x " + std::to_string(dims[0]) +
                         " points; expected 1 to " + std::to_string(k_max_surface_side) + " per side and at most " +
                         std::to_string(k_max_surface_points) + " in all");
    const double chunk_bytes = check_storage(dataset.get(), name, where.c_str(), {dims[0], dims[1]});
    if (chunk_bytes > double(1 << 27))
        refuse(name, where + " has chunks of " + std::to_string(static_cast<long long>(chunk_bytes / 8.0)) +
                         " values; expected at most 2^24");

    const Converter z = read_converter(dataset.get(), "Z Converter", name, where);
    const Converter x = read_converter(dataset.get(), "X Converter", name, where);
    const Converter y = read_converter(dataset.get(), "Y Converter", name, where);
    double z_um = 0.0;  // µm per stored value
    if (z.base_unit == "Fringes") {
        z_um = parameter(z, 1, name, "the wavelength (m)") * parameter(z, 2, name, "the interferometric scale factor") *
               parameter(z, 3, name, "the obliquity factor") * 1e6;
    } else {
        z_um = micrometres_per(z.base_unit);
        if (z_um == 0.0)
            refuse(name, "Z Converter's unit is '" + z.base_unit +
                             "'; expected Fringes or a length (Meters, MilliMeters, MicroMeters, NanoMeters, "
                             "Angstroms)");
    }
    double no_data = std::numeric_limits<double>::quiet_NaN();
    if (H5Aexists(dataset.get(), "No Data") > 0) {
        Id attribute(H5Aopen(dataset.get(), "No Data", H5P_DEFAULT), H5Aclose);
        const long long points = attribute.valid() ? attribute_points(attribute.get()) : -1;
        if (points < 1 || points > 16) refuse(name, where + ": attribute 'No Data' holds no single value");
        std::vector<double> values(static_cast<std::size_t>(points));
        if (H5Aread(attribute.get(), H5T_NATIVE_DOUBLE, values.data()) < 0)
            refuse(name, where + ": attribute 'No Data' is not a number");
        no_data = values[0];
    }

    MeasuredSurface s;
    s.format = "datx";
    s.rows = static_cast<int>(dims[0]);
    s.cols = static_cast<int>(dims[1]);
    s.dx_um = spacing_um(x, name, "X");
    s.dy_um = spacing_um(y, name, "Y");
    s.heights_um.resize(static_cast<std::size_t>(dims[0]) * static_cast<std::size_t>(dims[1]));
    if (H5Dread(dataset.get(), H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, s.heights_um.data()) < 0)
        refuse(name, where + " cannot be read (truncated or damaged file?)");
    for (double& h : s.heights_um)
        h = (h == no_data || !std::isfinite(h)) ? std::numeric_limits<double>::quiet_NaN() : h * z_um;
    s.metadata.push_back({"surface_dataset", where});
    s.metadata.push_back({"z_unit", z.base_unit});
    if (z.base_unit == "Fringes") {
        s.metadata.push_back({"wavelength_m", number(z.parameters[1])});
        s.metadata.push_back({"interferometric_scale_factor", number(z.parameters[2])});
        s.metadata.push_back({"obliquity_factor", number(z.parameters[3])});
    }
    return s;
}

}  // namespace

MeasuredSurface read_datx(const std::string& data, const std::string& name) { return read(data, name); }

}  // namespace wavebrdf::hdf5
