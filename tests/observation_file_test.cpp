// HDF5 observation files (observation_file.h): the round trip is exact (the slices to float32),
// any subset read equals the same observations of the full read, the shares of 1…4 ranks
// partition a file, hostile files (written here with the HDF5 C API: missing datasets, wrong
// types, ranks and dimensions, huge declared sizes, truncated or corrupted bytes) are refused
// with one line naming the file and the dataset and without a big allocation, and the CLI reads
// what it saved: `recover --observations x.h5` gives the heights it gives with the same
// observations as JSON.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <limits>
#include <functional>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "cli_util.h"
#include "test_util.h"
#include "wavebrdf/memory.h"
#include "wavebrdf/observation_file.h"
#include "wavebrdf/spectrum.h"

#ifdef WAVEBRDF_HAS_HDF5
#include <hdf5.h>
#endif

using namespace wavebrdf;
using namespace wavebrdf::test;

// In the sanitizer build: a huge malloc returns null, as it does without ASan, instead of
// ending the process. HDF5's own metadata cache asks malloc for sizes read from a damaged file
// (CorruptedBytesNeverCrash: 0xc4…b0 bytes) and handles the null; we cannot bound its
// allocations before they are made, only check that the failure is reported as one line.
// After such a failure HDF5 1.10 also keeps objects it cannot free (the library's own; our
// handles are all closed): LeakSanitizer is told to leave allocations made inside HDF5 alone.
#if defined(WAVEBRDF_ASAN)
extern "C" const char* __asan_default_options() { return "allocator_may_return_null=1"; }
extern "C" const char* __lsan_default_suppressions() { return "leak:libhdf5\n"; }
#endif

namespace {

// `count` observations at `positions` distinct footprint centres (each centre seen with
// several wavelengths, as an acquisition does), every query field varied.
std::vector<Observation> sample_observations(std::size_t count, int resolution, bool rgb, std::size_t positions = 3) {
    const Model models[] = {Model::OHS, Model::GHS, Model::ROHS, Model::RGHS, Model::Kirchhoff};
    std::mt19937_64 rng(17);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    std::vector<Observation> out;
    for (std::size_t i = 0; i < count; ++i) {
        Observation o;
        const std::size_t p = i % positions;
        o.query.x_um = 1.1 + 3.7 * double(p) + 1e-13;
        o.query.y_um = -2.3 + 0.1 * double(p * p);
        o.query.sigma_p_um = 2.0 + u(rng);
        o.query.omega_i = {0.3 * u(rng) - 0.15, 0.2 * u(rng)};
        o.query.model = models[i % 5];
        o.lambdas_um = rgb ? (i % 2 ? spectral_wavelengths_um(8) : std::vector<double>{0.45, 0.55, 0.65 + 1e-15})
                           : std::vector<double>{0.4 + 0.1 * u(rng)};
        o.resolution = resolution;
        o.reference.resize(std::size_t(resolution) * std::size_t(resolution) * std::size_t(o.channels()));
        for (float& v : o.reference) v = float(std::exp(8.0 * u(rng) - 6.0) - 0.001);
        out.push_back(std::move(o));
    }
    return out;
}

// `a` is `b` written and read: every query field and wavelength exact, the slice rounded to float.
void expect_same_rounded(const Observation& read, const Observation& written) {
    EXPECT_EQ(read.query.x_um, written.query.x_um);
    EXPECT_EQ(read.query.y_um, written.query.y_um);
    EXPECT_EQ(read.query.sigma_p_um, written.query.sigma_p_um);
    EXPECT_EQ(read.query.omega_i[0], written.query.omega_i[0]);
    EXPECT_EQ(read.query.omega_i[1], written.query.omega_i[1]);
    EXPECT_EQ(read.query.model, written.query.model);
    EXPECT_EQ(read.lambdas_um, written.lambdas_um);
    EXPECT_EQ(read.resolution, written.resolution);
    ASSERT_EQ(read.reference.size(), written.reference.size());
    for (std::size_t k = 0; k < read.reference.size(); ++k)
        ASSERT_EQ(read.reference[k], double(float(written.reference[k]))) << "value " << k;
}

void expect_identical(const Observation& a, const Observation& b) {
    EXPECT_EQ(a.query.x_um, b.query.x_um);
    EXPECT_EQ(a.query.y_um, b.query.y_um);
    EXPECT_EQ(a.query.sigma_p_um, b.query.sigma_p_um);
    EXPECT_EQ(a.query.omega_i, b.query.omega_i);
    EXPECT_EQ(a.query.model, b.query.model);
    EXPECT_EQ(a.lambdas_um, b.lambdas_um);
    EXPECT_EQ(a.resolution, b.resolution);
    EXPECT_EQ(a.reference, b.reference);
}

std::vector<std::size_t> all_indices(std::size_t n) {
    std::vector<std::size_t> v(n);
    for (std::size_t i = 0; i < n; ++i) v[i] = i;
    return v;
}

}  // namespace

TEST(ObservationFileTest, PathsAreRecognisedByExtension) {
    EXPECT_TRUE(is_hdf5_path("a/b.h5"));
    EXPECT_TRUE(is_hdf5_path("b.HDF5"));
    EXPECT_TRUE(is_hdf5_path("scan.cxi"));
    EXPECT_FALSE(is_hdf5_path("b.json"));
    EXPECT_FALSE(is_hdf5_path("h5"));
    EXPECT_FALSE(is_hdf5_path("dir.h5/file"));
}

#ifndef WAVEBRDF_HAS_HDF5

TEST(ObservationFileTest, WithoutHdf5TheFunctionsSaySo) {
    EXPECT_FALSE(built_with_hdf5());
    expect_throw_naming<std::runtime_error>([] { read_observations_hdf5("x.h5", {0}); }, "built without HDF5");
}

#else

namespace {

// Opens `path` read-write, runs `edit` on it, closes it.
void edit_hdf5_file(const fs::path& path, const std::function<void(hid_t)>& edit) {
    const hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
    ASSERT_GE(file, 0);
    edit(file);
    H5Fclose(file);
}

// Replaces dataset `name` by one of `type` and `dims` (filled with `fill` bytes when `write`).
void replace_dataset(hid_t file, const char* name, hid_t type, const std::vector<hsize_t>& dims, bool write = true,
                     const std::vector<hsize_t>& chunk = {}) {
    H5Ldelete(file, name, H5P_DEFAULT);
    const hid_t space = H5Screate_simple(int(dims.size()), dims.data(), nullptr);
    const hid_t dcpl = H5Pcreate(H5P_DATASET_CREATE);
    if (!chunk.empty()) H5Pset_chunk(dcpl, int(chunk.size()), chunk.data());
    const hid_t lcpl = H5Pcreate(H5P_LINK_CREATE);
    H5Pset_create_intermediate_group(lcpl, 1);
    const hid_t dataset = H5Dcreate2(file, name, type, space, lcpl, dcpl, H5P_DEFAULT);
    ASSERT_GE(dataset, 0) << name;
    if (write) {
        std::size_t count = 1;
        for (hsize_t d : dims) count *= std::size_t(d);
        std::vector<unsigned char> zeros(count * H5Tget_size(type), 0);
        H5Dwrite(dataset, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, zeros.data());
    }
    H5Dclose(dataset);
    H5Pclose(lcpl);
    H5Pclose(dcpl);
    H5Sclose(space);
}

// Overwrites the integers of dataset `name` with `values`.
void set_ints(hid_t file, const char* name, const std::vector<int>& values) {
    const hid_t dataset = H5Dopen2(file, name, H5P_DEFAULT);
    ASSERT_GE(dataset, 0);
    H5Dwrite(dataset, H5T_NATIVE_INT, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data());
    H5Dclose(dataset);
}

// Reading `path` fails with one line naming the file and every one of `needles`.
void expect_refused(const fs::path& path, const std::vector<std::string>& needles, double max_memory_gb = 1.0) {
    try {
        read_observations_file(path.string(), 0, 1, max_memory_gb);
        ADD_FAILURE() << "read; expected a refusal naming " << needles.front();
    } catch (const std::exception& e) {
        const std::string message = e.what();
        EXPECT_EQ(message.find('\n'), std::string::npos) << message;
        EXPECT_NE(message.find(path.string()), std::string::npos) << message;
        for (const std::string& needle : needles)
            EXPECT_NE(message.find(needle), std::string::npos) << "'" << message << "' does not name " << needle;
    }
}

}  // namespace

TEST(ObservationFileTest, RoundTripIsExactInFloatForRgbAndSingleWavelengths) {
    const fs::path dir = fresh_dir("observation_file");
    EXPECT_TRUE(built_with_hdf5());
    for (const bool rgb : {true, false}) {
        SCOPED_TRACE(rgb ? "rgb" : "single wavelength");
        const std::vector<Observation> written = sample_observations(7, rgb ? 5 : 6, rgb);
        const fs::path path = dir / (rgb ? "rgb.h5" : "mono.cxi");
        write_observations_hdf5(path.string(), written);
        const std::vector<Observation> read = read_observations_hdf5(path.string(), all_indices(written.size()));
        ASSERT_EQ(read.size(), written.size());
        for (std::size_t i = 0; i < read.size(); ++i) {
            SCOPED_TRACE(i);
            expect_same_rounded(read[i], written[i]);
        }
        // The index says the same without the slices.
        const ObservationIndex index = read_observation_index(path.string());
        ASSERT_EQ(index.size(), written.size());
        EXPECT_EQ(index.resolution, written[0].resolution);
        EXPECT_EQ(index.channels, rgb ? 3 : 1);
        for (std::size_t i = 0; i < index.size(); ++i) {
            EXPECT_EQ(index.lambdas_um[i], written[i].lambdas_um);
            EXPECT_EQ(index.positions_um()[i][0], written[i].query.x_um);
        }
        // No temporary is left beside it; writing again replaces it.
        for (const auto& entry : fs::directory_iterator(dir))
            EXPECT_EQ(entry.path().filename().string().find(".tmp"), std::string::npos) << entry.path();
        write_observations_file(path.string(), {written[2]});
        EXPECT_EQ(read_observation_index(path.string()).size(), 1u);
    }
}

TEST(ObservationFileTest, TheSameAsJsonThroughReadObservationsFile) {
    const fs::path dir = fresh_dir("observation_file");
    const std::vector<Observation> written = sample_observations(5, 4, true);
    write_observations_file((dir / "o.h5").string(), written);
    write_observations_file((dir / "o.json").string(), written, ReferenceStorage::Exr);  // float EXR
    const auto from_h5 = read_observations_file((dir / "o.h5").string());
    const auto from_json = read_observations_file((dir / "o.json").string());
    ASSERT_EQ(from_h5.size(), from_json.size());
    for (std::size_t i = 0; i < from_h5.size(); ++i) expect_identical(from_h5[i], from_json[i]);
    // A file with the HDF5 signature is read as HDF5 whatever its name.
    fs::copy_file(dir / "o.h5", dir / "o.dat");
    EXPECT_EQ(read_observations_file((dir / "o.dat").string()).size(), written.size());
}

TEST(ObservationFileTest, SubsetReadEqualsTheFullRead) {
    const fs::path dir = fresh_dir("observation_file");
    const std::vector<Observation> written = sample_observations(9, 8, false);
    const std::string path = (dir / "o.h5").string();
    write_observations_hdf5(path, written);
    const auto full = read_observations_hdf5(path, all_indices(written.size()));
    const std::vector<std::size_t> subset{7, 0, 3, 3, 8};
    const auto part = read_observations_hdf5(path, subset);
    ASSERT_EQ(part.size(), subset.size());
    for (std::size_t k = 0; k < subset.size(); ++k) expect_identical(part[k], full[subset[k]]);
    EXPECT_TRUE(read_observations_hdf5(path, {}).empty());
    EXPECT_THROW(read_observations_hdf5(path, {9}), std::out_of_range);
}

TEST(ObservationFileTest, RankSharesPartitionTheFile) {
    const fs::path dir = fresh_dir("observation_file");
    // 14 observations at 5 centres (several wavelengths each).
    const std::vector<Observation> written = sample_observations(14, 4, false, 5);
    write_observations_file((dir / "o.h5").string(), written);
    write_observations_file((dir / "o.json").string(), written);
    const auto full = read_observations_hdf5((dir / "o.h5").string(), all_indices(written.size()));
    for (int size = 1; size <= 4; ++size) {
        SCOPED_TRACE(size);
        std::vector<int> owner(written.size(), -1);
        for (int rank = 0; rank < size; ++rank) {
            std::vector<std::size_t> indices, json_indices;
            const auto share = read_observations_file((dir / "o.h5").string(), rank, size, 0.0, &indices);
            const auto json_share = read_observations_file((dir / "o.json").string(), rank, size, 0.0, &json_indices);
            EXPECT_EQ(indices, json_indices);
            ASSERT_EQ(share.size(), indices.size());
            EXPECT_TRUE(std::is_sorted(indices.begin(), indices.end()));
            for (std::size_t k = 0; k < indices.size(); ++k) {
                ASSERT_LT(indices[k], written.size());
                EXPECT_EQ(owner[indices[k]], -1) << "observation " << indices[k] << " in two shares";
                owner[indices[k]] = rank;
                expect_identical(share[k], full[indices[k]]);
            }
        }
        for (std::size_t i = 0; i < written.size(); ++i) {
            EXPECT_GE(owner[i], 0) << "observation " << i << " in no share";
            // Every observation of one footprint centre is on one rank.
            for (std::size_t j = 0; j < written.size(); ++j)
                if (written[i].query.x_um == written[j].query.x_um) {
                    EXPECT_EQ(owner[i], owner[j]);
                }
        }
    }
    EXPECT_THROW(read_observations_file((dir / "o.h5").string(), 2, 2), std::invalid_argument);
}

TEST(ObservationFileTest, WritingRefusesMixedOrInvalidSets) {
    const fs::path dir = fresh_dir("observation_file");
    std::vector<Observation> mixed = sample_observations(2, 4, false);
    mixed.push_back(sample_observations(1, 5, false)[0]);
    expect_throw_naming<std::invalid_argument>([&] { write_observations_hdf5((dir / "m.h5").string(), mixed); },
                                               "observation 2 has resolution 5");
    EXPECT_THROW(write_observations_hdf5((dir / "e.h5").string(), {}), std::invalid_argument);
    std::vector<Observation> huge = sample_observations(1, 2, false);
    huge[0].reference[1] = std::numeric_limits<float>::infinity();  // 1e300 rounded to float
    expect_throw_naming<std::domain_error>([&] { write_observations_hdf5((dir / "h.h5").string(), huge); },
                                           "is not finite");
    EXPECT_FALSE(fs::exists(dir / "m.h5") || fs::exists(dir / "e.h5") || fs::exists(dir / "h.h5"));
    // A directory in the way is not replaced.
    fs::create_directories(dir / "d.h5");
    EXPECT_THROW(write_observations_hdf5((dir / "d.h5").string(), sample_observations(1, 2, false)),
                 std::runtime_error);
}

TEST(ObservationFileTest, HostileFilesAreRefusedWithOneLine) {
    const fs::path dir = fresh_dir("observation_file");
    const std::vector<Observation> good = sample_observations(4, 4, false);
    int made = 0;
    // A fresh copy of the good file, edited.
    auto hostile = [&](const std::function<void(hid_t)>& edit) {
        const fs::path path = dir / ("hostile_" + std::to_string(made++) + ".h5");
        write_observations_hdf5(path.string(), good);
        edit_hdf5_file(path, edit);
        return path;
    };
    expect_refused(hostile([](hid_t f) { H5Ldelete(f, "/entry_1/wavebrdf_1/x_um", H5P_DEFAULT); }),
                   {"/entry_1/wavebrdf_1/x_um", "missing"});
    expect_refused(hostile([](hid_t f) { H5Ldelete(f, "/entry_1/data_1", H5P_DEFAULT); }),
                   {"/entry_1/data_1/data", "missing"});
    expect_refused(hostile([](hid_t f) { replace_dataset(f, "/entry_1/wavebrdf_1/model", H5T_IEEE_F64LE, {4}); }),
                   {"/entry_1/wavebrdf_1/model", "wrong type"});
    expect_refused(hostile([](hid_t f) {
                       replace_dataset(f, "/entry_1/data_1/data", H5T_STD_I32LE, {4, 1, 4, 4});
                   }),
                   {"/entry_1/data_1/data", "wrong type"});
    expect_refused(hostile([](hid_t f) {
                       replace_dataset(f, "/entry_1/data_1/data", H5T_IEEE_F32LE, {4, 4, 4});
                   }),
                   {"/entry_1/data_1/data", "rank 3"});
    expect_refused(hostile([](hid_t f) {
                       replace_dataset(f, "/entry_1/data_1/data", H5T_IEEE_F32LE, {4, 2, 4, 4});
                   }),
                   {"/entry_1/data_1/data", "2 channels"});
    expect_refused(hostile([](hid_t f) {
                       replace_dataset(f, "/entry_1/data_1/data", H5T_IEEE_F32LE, {4, 1, 4, 5});
                   }),
                   {"/entry_1/data_1/data", "n x n"});
    expect_refused(hostile([](hid_t f) {
                       replace_dataset(f, "/entry_1/wavebrdf_1/light", H5T_IEEE_F64LE, {4, 3});
                   }),
                   {"/entry_1/wavebrdf_1/light", "4 x 3", "4 x 2"});
    expect_refused(hostile([](hid_t f) { replace_dataset(f, "/entry_1/wavebrdf_1/y_um", H5T_IEEE_F64LE, {5}); }),
                   {"/entry_1/wavebrdf_1/y_um", "dims 5"});
    expect_refused(hostile([](hid_t f) {
                       set_ints(f, "/entry_1/wavebrdf_1/model", {0, 1, 9, 0});
                   }),
                   {"/entry_1/wavebrdf_1/model", "observation 2", "code 9"});
    expect_refused(hostile([](hid_t f) {
                       set_ints(f, "/entry_1/wavebrdf_1/wavelength_count", {1, 0, 1, 1});
                   }),
                   {"/entry_1/wavebrdf_1/wavelength_count", "observation 1"});
    expect_refused(hostile([](hid_t f) { H5Adelete(f, "wavebrdf_format"); }), {"wavebrdf_format", "missing"});
    // Zero sigma_p: the query's own validation, named.
    expect_refused(hostile([](hid_t f) { replace_dataset(f, "/entry_1/wavebrdf_1/sigma_p_um", H5T_IEEE_F64LE, {4}); }),
                   {"/entry_1/wavebrdf_1", "observation 0"});
    // A non-finite slice value.
    expect_refused(hostile([](hid_t f) {
                       const hid_t d = H5Dopen2(f, "/entry_1/data_1/data", H5P_DEFAULT);
                       std::vector<float> v(4 * 16, NAN);
                       H5Dwrite(d, H5T_NATIVE_FLOAT, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data());
                       H5Dclose(d);
                   }),
                   {"/entry_1/data_1/data", "not finite"});
    // Not HDF5 at all, truncated, empty.
    {
        const fs::path path = dir / "text.h5";
        std::ofstream(path) << "{\"observations\": []}";
        expect_refused(path, {"cannot open it as HDF5"});
        const fs::path good_path = dir / "good.h5";
        write_observations_hdf5(good_path.string(), good);
        const auto size = fs::file_size(good_path);
        for (const auto keep : {size / 2, size - 1, std::uintmax_t(0)}) {
            const fs::path cut = dir / ("cut_" + std::to_string(keep) + ".h5");
            fs::copy_file(good_path, cut);
            fs::resize_file(cut, keep);
            expect_refused(cut, {".h5"});
        }
    }
}

TEST(ObservationFileTest, HugeDeclaredSizesAreRefusedBeforeAllocating) {
    const fs::path dir = fresh_dir("observation_file");
    const std::vector<Observation> good = sample_observations(4, 4, false);
    const fs::path path = dir / "huge.h5";
    // Too many observations.
    write_observations_hdf5(path.string(), good);
    edit_hdf5_file(path, [](hid_t f) {
        replace_dataset(f, "/entry_1/data_1/data", H5T_IEEE_F32LE, {200000000, 1, 4, 4}, false, {1, 1, 4, 4});
    });
    expect_refused(path, {"/entry_1/data_1/data", "200000000 observations", "1e8"});
    // A slice too large, and many wavelengths.
    write_observations_hdf5(path.string(), good);
    edit_hdf5_file(path, [](hid_t f) {
        replace_dataset(f, "/entry_1/data_1/data", H5T_IEEE_F32LE, {4, 1, 100000, 100000}, false, {1, 1, 64, 64});
    });
    expect_refused(path, {"/entry_1/data_1/data", "100000"});
    write_observations_hdf5(path.string(), good);
    edit_hdf5_file(path, [](hid_t f) {
        replace_dataset(f, "/entry_1/wavebrdf_1/wavelengths_um", H5T_IEEE_F64LE, {4, 100000});
    });
    expect_refused(path, {"/entry_1/wavebrdf_1/wavelengths_um", "100000"});
    // 1e8 observations of 8192² declared in a few kilobytes: refused without allocating (the
    // index's metadata were never written; the slices would need ~27 PB).
    write_observations_hdf5(path.string(), good);
    edit_hdf5_file(path, [](hid_t f) {
        const hsize_t n = 100000000;
        replace_dataset(f, "/entry_1/data_1/data", H5T_IEEE_F32LE, {n, 1, 8192, 8192}, false, {1, 1, 8192, 8192});
        for (const char* name :
             {"/entry_1/wavebrdf_1/x_um", "/entry_1/wavebrdf_1/y_um", "/entry_1/wavebrdf_1/sigma_p_um"})
            replace_dataset(f, name, H5T_IEEE_F64LE, {n}, false);
        replace_dataset(f, "/entry_1/wavebrdf_1/light", H5T_IEEE_F64LE, {n, 2}, false);
        replace_dataset(f, "/entry_1/wavebrdf_1/model", H5T_STD_I32LE, {n}, false);
        replace_dataset(f, "/entry_1/wavebrdf_1/wavelength_count", H5T_STD_I32LE, {n}, false);
        replace_dataset(f, "/entry_1/wavebrdf_1/wavelengths_um", H5T_IEEE_F64LE, {n, 1}, false);
    });
    EXPECT_LT(fs::file_size(path), 100000u);
    expect_refused(path, {"/entry_1/wavebrdf_1/x_um", "never written"}, 100.0);
    expect_throw_naming<OutOfMemory>([&] { read_observations_file(path.string(), 0, 1, 0.5); }, "500 MB");
    const double peak = child_peak_memory_bytes([&] {
        try {
            read_observations_file(path.string(), 0, 1, 100.0);
        } catch (const std::runtime_error&) {
            return true;
        }
        return false;
    });
    const double before = child_peak_memory_bytes([] { return true; });
    ASSERT_GT(peak, 0.0);
    EXPECT_LT(peak - before, 64e6) << "peak " << peak << " bytes, an idle child " << before;
}

// Random bytes of a valid file corrupted: every read either gives valid observations or throws
// a std::exception, never crashes (a fuzz-like sweep; fuzz/ has the libFuzzer targets).
TEST(ObservationFileTest, CorruptedBytesNeverCrash) {
    const fs::path dir = fresh_dir("observation_file");
    const std::vector<Observation> good = sample_observations(3, 4, true);
    const fs::path good_path = dir / "good.h5";
    write_observations_hdf5(good_path.string(), good);
    std::string bytes = read_text(good_path);
    std::mt19937_64 rng(5);
    int refused = 0, read = 0;
    for (int trial = 0; trial < 150; ++trial) {
        std::string damaged = bytes;
        const int flips = 1 + int(rng() % 4);
        for (int k = 0; k < flips; ++k) damaged[rng() % damaged.size()] = char(rng() & 0xff);
        const fs::path path = dir / "damaged.h5";
        std::ofstream(path, std::ios::binary | std::ios::trunc) << damaged;
        try {
            const auto observations = read_observations_file(path.string(), 0, 1, 1.0);
            for (std::size_t i = 0; i < observations.size(); ++i) validate(observations[i], i);
            ++read;
        } catch (const std::exception& e) {
            EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << e.what();
            ++refused;
        }
    }
    EXPECT_EQ(read + refused, 150);
}

TEST(ObservationFileTest, RecoverReadsTheObservationsItSavedAsHdf5) {
    const fs::path dir = fresh_dir("observation_file");
    // A quick run (one wavelength, coarse slices, few iterations): the point is the same input.
    const std::string small =
        " --size 8 --texel-um 2 --sigma-p-um 3 --height-range-um 0.1 --seed 3 --resolution 16 --lambdas-um 0.5 "
        "--field-iterations 3 --refine-iterations 2 --no-plots --quiet";
    const CliResult saved = run_cli(dir, "recover" + small + " --save-observations obs.h5 --out run");
    ASSERT_EQ(saved.exit_code, 0) << saved.err;
    ASSERT_TRUE(fs::exists(dir / "obs.h5"));
    EXPECT_FALSE(fs::exists(dir / "run" / "observations.json"));
    // The same observations as JSON (inline: the doubles read from the HDF5 file, exactly).
    const auto observations = read_observations_file((dir / "obs.h5").string());
    write_observations_json((dir / "obs.json").string(), observations);
    const CliResult from_h5 = run_cli(dir, "recover --observations obs.h5" + small + " --out h5");
    ASSERT_EQ(from_h5.exit_code, 0) << from_h5.err;
    const CliResult from_json = run_cli(dir, "recover --observations obs.json" + small + " --out json");
    ASSERT_EQ(from_json.exit_code, 0) << from_json.err;
    const std::string heights = read_text(dir / "h5" / "estimate_height.npy");
    EXPECT_FALSE(heights.empty());
    EXPECT_EQ(heights, read_text(dir / "json" / "estimate_height.npy"));
    // A damaged file: one line naming it.
    std::ofstream(dir / "bad.h5") << "not hdf5";
    expect_one_line_naming(run_cli(dir, "recover --observations bad.h5" + small + " --out bad"), {"bad.h5"});
}

#endif
