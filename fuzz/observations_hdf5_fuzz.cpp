// libFuzzer target: the HDF5 observation reader (read_observation_index and
// read_observations_file) on well-formed HDF5 files with hostile contents. The input is a
// recipe, not the file: for every part of the layout (docs/observations_hdf5.md) it says whether
// to write the part as specified, leave it out, give it another class, rank or dims (up to 2^40
// values, never written: chunked storage reads back fill values), another layout or filters,
// external raw storage, a link or a group in its place, and which values to store (NaN, ±inf,
// 0, negatives, 1e300 among ordinary ones). The HDF5 library writes that file and our reader
// reads it. Every check of observation_hdf5.cpp is reached this way; a recipe that asks for the
// layout as specified with valid values must be read (a refusal aborts).
//
// Byte-level corruption of the container is HDF5's own parser at work, and HDF5 1.10 leaks and
// overflows on some malformed headers (fuzz/lsan_hdf5.supp cites them): that is
// observations_hdf5_bytes_fuzz, run on its saved inputs in CI (fuzz/README.md).
#include <fuzzer/FuzzedDataProvider.h>
#include <hdf5.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <limits>
#include <string>
#include <vector>

#include "fuzz_util.h"
#include "wavebrdf/observation_file.h"

namespace {

constexpr const char* k_format = "wavebrdf_observations 1";

// What to do with one part of the layout.
enum class Part : std::uint8_t { AsSpecified, Missing, OtherClass, OtherShape, Link, Group, External, count };

Part pick_part(FuzzedDataProvider& in) {
    // Half of the draws keep a part as specified, so most files get past the first checks.
    const auto b = in.ConsumeIntegral<std::uint8_t>();
    if (b < 128) return Part::AsSpecified;
    return static_cast<Part>(1 + b % (static_cast<int>(Part::count) - 1));
}

double pick_double(FuzzedDataProvider& in, double ordinary) {
    switch (in.ConsumeIntegralInRange<int>(0, 15)) {
        case 0: return std::numeric_limits<double>::quiet_NaN();
        case 1: return std::numeric_limits<double>::infinity();
        case 2: return -std::numeric_limits<double>::infinity();
        case 3: return 0.0;
        case 4: return -ordinary;
        case 5: return 1e300;
        case 6: return in.ConsumeFloatingPoint<double>();
        default: return ordinary;
    }
}

hsize_t pick_dim(FuzzedDataProvider& in, hsize_t specified) {
    switch (in.ConsumeIntegralInRange<int>(0, 7)) {
        case 0: return 0;
        case 1: return specified + 1;
        case 2: return specified > 0 ? specified - 1 : 1;
        case 3: return hsize_t(1) << 31;
        case 4: return hsize_t(1) << 40;
        case 5: return in.ConsumeIntegralInRange<hsize_t>(0, 70000);
        default: return specified;
    }
}

// Writes the files of one recipe; `clean` stays true while every part is as specified with
// valid values.
class Writer {
public:
    Writer(FuzzedDataProvider& in, hid_t file) : in_(in), file_(file) {}
    bool clean = true;

    // A dataset at `path` of native type `type` and dims `dims` (values from `values`, cycled),
    // or whatever the recipe puts there instead.
    void dataset(const char* path, hid_t type, std::vector<hsize_t> dims, const std::vector<double>& values,
                 bool slices = false) {
        const Part part = pick_part(in_);
        if (part != Part::AsSpecified) clean = false;
        switch (part) {
            case Part::Missing: return;
            case Part::Link:
                if (in_.ConsumeBool())
                    H5Lcreate_soft(in_.ConsumeBool() ? "/entry_1/wavebrdf_1/x_um" : "/nowhere", file_, path,
                                   H5P_DEFAULT, H5P_DEFAULT);
                else
                    H5Lcreate_external("other.h5", "/data", file_, path, H5P_DEFAULT, H5P_DEFAULT);
                return;
            case Part::Group: {
                const hid_t g = H5Gcreate2(file_, path, lcpl(), H5P_DEFAULT, H5P_DEFAULT);
                if (g >= 0) H5Gclose(g);
                return;
            }
            case Part::OtherClass:
                type = in_.PickValueInArray({H5T_NATIVE_INT, H5T_NATIVE_DOUBLE, H5T_NATIVE_FLOAT, H5T_NATIVE_SCHAR,
                                             H5T_NATIVE_UINT64, H5T_NATIVE_USHORT});
                break;
            case Part::OtherShape: {
                const int rank = in_.ConsumeIntegralInRange<int>(0, 5);
                std::vector<hsize_t> other(std::size_t(rank), 1);
                for (int k = 0; k < rank; ++k) other[k] = pick_dim(in_, k < int(dims.size()) ? dims[k] : 1);
                dims = other;
                break;
            }
            default: break;
        }
        write(path, type, dims, values, slices, part == Part::External);
    }

    // The root's format attribute, or what the recipe puts there instead.
    void format_attribute() {
        const Part part = pick_part(in_);
        if (part == Part::Missing) {
            clean = false;
            return;
        }
        std::string text = k_format;
        if (part != Part::AsSpecified) {
            clean = false;
            text = in_.ConsumeRandomLengthString(300);
        }
        const bool variable = in_.ConsumeBool();
        const hid_t type = H5Tcopy(H5T_C_S1);
        H5Tset_size(type, variable ? H5T_VARIABLE : std::max<std::size_t>(text.size(), 1));
        if (in_.ConsumeBool()) H5Tset_cset(type, H5T_CSET_UTF8);
        const bool array = part == Part::OtherShape;
        const hsize_t two = 2;
        const hid_t space = array ? H5Screate_simple(1, &two, nullptr) : H5Screate(H5S_SCALAR);
        const hid_t attribute = H5Acreate2(file_, "wavebrdf_format", part == Part::OtherClass ? H5T_NATIVE_INT : type,
                                           space, H5P_DEFAULT, H5P_DEFAULT);
        if (attribute >= 0 && part != Part::OtherClass && !array) {
            if (variable) {
                const char* p = text.c_str();
                H5Awrite(attribute, type, &p);
            } else {
                H5Awrite(attribute, type, text.data());
            }
        }
        if (attribute >= 0) H5Aclose(attribute);
        H5Sclose(space);
        H5Tclose(type);
    }

private:
    static hid_t lcpl() {
        static const hid_t list = [] {
            const hid_t l = H5Pcreate(H5P_LINK_CREATE);
            H5Pset_create_intermediate_group(l, 1);
            return l;
        }();
        return list;
    }

    void write(const char* path, hid_t type, const std::vector<hsize_t>& dims, const std::vector<double>& values,
               bool slices, bool external) {
        const hid_t space = dims.empty() ? H5Screate(H5S_SCALAR)
                                         : H5Screate_simple(int(dims.size()), dims.data(), nullptr);
        if (space < 0) return;
        double count = 1;
        for (hsize_t d : dims) count *= double(d);
        const hid_t dcpl = H5Pcreate(H5P_DATASET_CREATE);
        // The layout: contiguous (the only one external storage allows), compact, or chunked
        // with the recipe's chunk dims and filters. Large datasets are chunked and never
        // written, so the file stays small.
        const int layout = external ? 0 : count > 4096 ? 2 : in_.ConsumeIntegralInRange<int>(0, 2);
        if (external) {
            clean = false;
            H5Pset_external(dcpl, in_.ConsumeBool() ? "/etc/passwd" : "raw.bin", 0, H5F_UNLIMITED);
        } else if (layout == 1 && count * 8 < 16000) {
            H5Pset_layout(dcpl, H5D_COMPACT);
        } else if (layout == 2 && !dims.empty() && count > 0) {
            std::vector<hsize_t> chunk(dims.size());
            for (std::size_t k = 0; k < dims.size(); ++k) {
                const hsize_t largest = std::min<hsize_t>(dims[k], slices && k == 0 ? 2 : 64);
                chunk[k] = std::max<hsize_t>(1, in_.ConsumeIntegralInRange<hsize_t>(1, std::max<hsize_t>(largest, 1)));
            }
            H5Pset_chunk(dcpl, int(chunk.size()), chunk.data());
            if (in_.ConsumeBool()) H5Pset_shuffle(dcpl);
            if (in_.ConsumeBool()) H5Pset_deflate(dcpl, 1);
            if (in_.ConsumeBool()) H5Pset_fletcher32(dcpl);
        }
        const hid_t dataset = H5Dcreate2(file_, path, type, space, lcpl(), dcpl, H5P_DEFAULT);
        if (dataset >= 0) {
            if (count <= 4096 && !external) {
                std::vector<double> data(static_cast<std::size_t>(count));
                for (std::size_t i = 0; i < data.size(); ++i) data[i] = values.empty() ? 0.0 : values[i % values.size()];
                H5Dwrite(dataset, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, data.data());
            }
            H5Dclose(dataset);
        }
        H5Pclose(dcpl);
        H5Sclose(space);
    }

    FuzzedDataProvider& in_;
    hid_t file_;
};

// The recipe's file at `path`; returns whether every part was as specified with valid values.
bool write_recipe(FuzzedDataProvider& in, const std::string& path) {
    const hsize_t count = in.ConsumeIntegralInRange<hsize_t>(1, 3);
    const bool spectral = in.ConsumeBool();
    const hsize_t channels = spectral ? 3 : 1;
    const hsize_t n = in.ConsumeIntegralInRange<hsize_t>(1, 4);
    const hsize_t wavelengths = spectral ? in.ConsumeIntegralInRange<hsize_t>(2, 4) : 1;

    const hid_t file = H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    if (file < 0) std::abort();  // our own scratch directory
    Writer w(in, file);
    w.format_attribute();
    // Hostile values (NaN, infinities, negatives, 1e300) anywhere, or ordinary ones everywhere.
    const bool hostile_values = in.ConsumeBool();
    if (hostile_values) w.clean = false;
    auto values = [&](double ordinary, std::size_t size) {
        std::vector<double> v(size, ordinary);
        if (hostile_values)
            for (double& x : v) x = pick_double(in, ordinary);
        return v;
    };
    std::vector<double> slice_values = values(0.5, 8);
    for (std::size_t i = 0; i < slice_values.size() && !hostile_values; ++i) slice_values[i] = 0.25 * double(i);
    w.dataset("/entry_1/data_1/data", H5T_NATIVE_FLOAT, {count, channels, n, n}, slice_values, true);
    w.dataset("/entry_1/wavebrdf_1/x_um", H5T_NATIVE_DOUBLE, {count}, values(1.0, 3));
    w.dataset("/entry_1/wavebrdf_1/y_um", H5T_NATIVE_DOUBLE, {count}, values(-1.0, 3));
    w.dataset("/entry_1/wavebrdf_1/sigma_p_um", H5T_NATIVE_DOUBLE, {count}, values(5.0, 3));
    w.dataset("/entry_1/wavebrdf_1/light", H5T_NATIVE_DOUBLE, {count, 2}, values(0.1, 6));
    w.dataset("/entry_1/wavebrdf_1/model", H5T_NATIVE_INT, {count}, values(double(in.ConsumeIntegralInRange<int>(0, 4)), 3));
    w.dataset("/entry_1/wavebrdf_1/wavelength_count", H5T_NATIVE_INT, {count}, values(double(wavelengths), 3));
    std::vector<double> lambdas;
    for (hsize_t k = 0; k < wavelengths; ++k) lambdas.push_back(0.45 + 0.1 * double(k));
    w.dataset("/entry_1/wavebrdf_1/wavelengths_um", H5T_NATIVE_DOUBLE, {count, wavelengths},
              hostile_values ? values(0.5, 12) : lambdas);
    // The optional per-pixel weights (absent is as specified too).
    if (in.ConsumeBool())
        w.dataset("/entry_1/wavebrdf_1/weights", H5T_NATIVE_FLOAT, {count, n, n}, values(1.0, 5), true);
    if (H5Fclose(file) < 0) std::abort();
    return w.clean;
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);  // our reader says what failed, in one line
    return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    FuzzedDataProvider in(data, size);
    const std::string path = wavebrdf::fuzz::scratch_dir() + "/observations.h5";
    const bool clean = write_recipe(in, path);
    bool index_read = false, observations_read = false;
    // 0.25 GB: a small file may not make the reader allocate more than this.
    wavebrdf::fuzz::expect_clean([&] {
        wavebrdf::read_observation_index(path, 0.25);
        index_read = true;
    });
    wavebrdf::fuzz::expect_clean([&] {
        const auto observations = wavebrdf::read_observations_file(path, 0, 1, 0.25);
        // Documented: at least one, each validated.
        if (observations.empty()) std::abort();
        for (std::size_t i = 0; i < observations.size(); ++i) wavebrdf::validate(observations[i], i);
        observations_read = true;
    });
    // The layout as specified with valid values is a file the reader must accept.
    if (clean && !(index_read && observations_read)) std::abort();
    return 0;
}
