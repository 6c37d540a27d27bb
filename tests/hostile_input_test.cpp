// Hostile input files (the readers of observation_file.h, io.h and table.h): HDF5 observation
// files that point outside themselves (external raw storage, external links, virtual datasets),
// carry a corrupt chunk layout, declare chunks they never wrote or need a filter this build
// lacks are refused with one line before any read; attributes as h5py writes them are read;
// FIFOs and devices given as any input are refused instead of blocking or reading forever.
// Every hostile file is written here with the HDF5 C API or the POSIX calls, not by our writer's
// options. Reads run in a child process with an alarm, so a hang fails the test instead of
// stopping the suite.
#include <gtest/gtest.h>

#include <signal.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <fstream>
#include <functional>
#include <string>
#include <vector>

#include "cli_util.h"
#include "wavebrdf/design_plate.h"
#include "wavebrdf/design_run.h"
#include "wavebrdf/invert.h"
#include "wavebrdf/input_files.h"
#include "wavebrdf/io.h"
#include "wavebrdf/observation_file.h"
#include "wavebrdf/table.h"

#ifdef WAVEBRDF_HAS_HDF5
#include <hdf5.h>
#endif

using namespace wavebrdf;
using namespace wavebrdf::test;

namespace {

std::vector<Observation> small_set(int n = 8) {
    std::vector<Observation> out;
    for (int i = 0; i < 4; ++i) {
        Observation o;
        o.query.x_um = 1.0 + i;
        o.query.sigma_p_um = 2.0;
        o.lambdas_um = {0.5};
        o.resolution = n;
        o.reference.assign(std::size_t(n) * std::size_t(n), 0.25f + float(i));
        out.push_back(std::move(o));
    }
    return out;
}

// Runs `read` in a child with a 20 s alarm. Returns the exception's message it threw (one
// line expected), "" when it returned normally, or a description of the child's death.
std::string message_of_read_in_child(const fs::path& dir, const std::function<void()>& read) {
    const fs::path out = dir / "child_message.txt";
    fs::remove(out);
    const pid_t pid = ::fork();
    if (pid == 0) {
        ::alarm(20);
        std::string message;
        try {
            read();
        } catch (const std::exception& e) {
            message = e.what();
        }
        std::ofstream(out) << message;
        std::_Exit(0);
    }
    int status = 0;
    ::waitpid(pid, &status, 0);
    if (WIFSIGNALED(status))
        return std::string("child died of signal ") + std::to_string(WTERMSIG(status)) +
               (WTERMSIG(status) == SIGALRM ? " (the read hung for 20 s)" : "");
    return read_text(out);
}

void expect_refused_naming(const std::string& message, const std::vector<std::string>& needles) {
    EXPECT_FALSE(message.empty()) << "read without an error";
    EXPECT_EQ(message.find('\n'), std::string::npos) << message;
    EXPECT_EQ(message.find("child died"), std::string::npos) << message;
    for (const std::string& needle : needles)
        EXPECT_NE(message.find(needle), std::string::npos) << "'" << message << "' does not name '" << needle << "'";
}

}  // namespace

// A FIFO or a device given as any input is refused at once, naming what it is.
TEST(HostileInputTest, FifosAndDevicesAreRefusedByEveryReader) {
    const fs::path dir = fresh_dir("hostile");
    for (const char* name : {"obs.json", "obs.h5", "slice.exr", "table.exr", "height.exr", "positions.json",
                             "pattern.png", "picture.png", "spec.json", "target.exr"})
        ASSERT_EQ(::mkfifo((dir / name).c_str(), 0600), 0) << name;
    fs::create_symlink("/dev/zero", dir / "zero.json");
    const auto path = [&](const char* name) { return (dir / name).string(); };
    expect_refused_naming(message_of_read_in_child(dir, [&] { read_observations_file(path("obs.json")); }),
                          {"obs.json", "is a FIFO", "expected a regular file"});
    expect_refused_naming(message_of_read_in_child(dir, [&] { read_observations_file(path("obs.h5")); }),
                          {"obs.h5", "is a FIFO"});
    expect_refused_naming(message_of_read_in_child(dir, [&] { read_slice_exr(path("slice.exr")); }),
                          {"slice.exr", "is a FIFO"});
    expect_refused_naming(message_of_read_in_child(dir, [&] { read_brdf_table(path("table.exr")); }),
                          {"table.exr", "is a FIFO"});
    expect_refused_naming(message_of_read_in_child(dir, [&] { read_heightfield_exr(path("height.exr")); }),
                          {"height.exr", "is a FIFO"});
    expect_refused_naming(message_of_read_in_child(dir, [&] { read_positions_json(path("positions.json")); }),
                          {"positions.json", "is a FIFO"});
    // The design's inputs: a pattern's image, a plate's picture, an iridescent spec, a brdf table.
    expect_refused_naming(message_of_read_in_child(dir, [&] { parse_design_target("pattern:" + path("pattern.png")); }),
                          {"pattern.png", "is a FIFO"});
    expect_refused_naming(message_of_read_in_child(dir, [&] { read_plate_picture(path("picture.png")); }),
                          {"picture.png", "is a FIFO"});
    expect_refused_naming(
        message_of_read_in_child(dir, [&] { parse_design_target("iridescent:" + path("spec.json")); }),
        {"spec.json", "is a FIFO"});
    expect_refused_naming(message_of_read_in_child(dir, [&] { parse_design_target("brdf:" + path("target.exr")); }),
                          {"target.exr", "is a FIFO"});
    expect_refused_naming(message_of_read_in_child(dir, [&] { read_observations_file(path("zero.json")); }),
                          {"zero.json", "is a character device"});

    // A slice named in observations JSON that is a FIFO (the first one read: the child of a fork
    // must not decode an EXR, whose thread pool stayed in the parent).
    write_observations_file(path("set.json"), small_set(), ReferenceStorage::Exr);
    const fs::path slice = dir / "set" / "slice_0000.exr";
    ASSERT_TRUE(fs::exists(slice));
    fs::remove(slice);
    ASSERT_EQ(::mkfifo(slice.c_str(), 0600), 0);
    expect_refused_naming(message_of_read_in_child(dir, [&] { read_observations_file(path("set.json")); }),
                          {"slice_0000.exr", "is a FIFO"});
}

// A non-finite slice value is named by its pixel and channel, not as a "value" that is an index.
TEST(HostileInputTest, NonFiniteSliceValueNamesItsPixel) {
    std::vector<Observation> set = small_set(4);
    set[1].reference[2 * 4 + 3] = NAN;
    try {
        validate(set[1], 1);
        ADD_FAILURE() << "a NaN passed";
    } catch (const std::exception& e) {
        expect_refused_naming(e.what(), {"observation 1", "pixel (2, 3) channel 0 is not finite (NaN)"});
    }
}

#ifdef WAVEBRDF_HAS_HDF5

namespace {

constexpr const char* k_data = "/entry_1/data_1/data";
constexpr const char* k_x = "/entry_1/wavebrdf_1/x_um";

void edit_file(const fs::path& path, const std::function<void(hid_t)>& edit) {
    const hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
    ASSERT_GE(file, 0);
    edit(file);
    H5Fclose(file);
}

// A new dataset `name` (the old one deleted) of float64 `dims` with the creation properties
// `dcpl` (caller's), written with `values` when not empty.
void replace(hid_t file, const char* name, hid_t type, const std::vector<hsize_t>& dims, hid_t dcpl,
             const std::vector<double>& values = {}) {
    H5Ldelete(file, name, H5P_DEFAULT);
    const hid_t space = H5Screate_simple(int(dims.size()), dims.data(), nullptr);
    const hid_t dataset = H5Dcreate2(file, name, type, space, H5P_DEFAULT, dcpl, H5P_DEFAULT);
    ASSERT_GE(dataset, 0) << name;
    if (!values.empty()) H5Dwrite(dataset, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data());
    H5Dclose(dataset);
    H5Sclose(space);
}

}  // namespace

TEST(HostileInputTest, Hdf5ObjectsOutsideTheFileAreRefused) {
    const fs::path dir = fresh_dir("hostile");
    const std::vector<Observation> good = small_set();
    int made = 0;
    auto hostile = [&](const std::function<void(hid_t)>& edit) {
        const fs::path path = dir / ("hostile_" + std::to_string(made++) + ".h5");
        write_observations_file(path.string(), good);
        edit_file(path, edit);
        return path.string();
    };
    const auto read = [&](const std::string& path) {
        return message_of_read_in_child(dir, [&] { read_observations_file(path, 0, 1, 1.0); });
    };
    // External raw storage: x_um's values in /etc/passwd, the slices in /dev/zero.
    expect_refused_naming(read(hostile([](hid_t f) {
                              const hid_t dcpl = H5Pcreate(H5P_DATASET_CREATE);
                              H5Pset_external(dcpl, "/etc/passwd", 0, 32);
                              replace(f, k_x, H5T_IEEE_F64LE, {4}, dcpl);
                              H5Pclose(dcpl);
                          })),
                          {k_x, "external raw storage"});
    expect_refused_naming(read(hostile([](hid_t f) {
                              const hid_t dcpl = H5Pcreate(H5P_DATASET_CREATE);
                              H5Pset_external(dcpl, "/dev/zero", 0, H5F_UNLIMITED);
                              replace(f, k_data, H5T_IEEE_F32LE, {4, 1, 8, 8}, dcpl);
                              H5Pclose(dcpl);
                          })),
                          {k_data, "external raw storage"});
    // An external link to a FIFO (the lookup would open it and block) and to a regular file.
    ASSERT_EQ(::mkfifo((dir / "fifo.h5").c_str(), 0600), 0);
    expect_refused_naming(read(hostile([&](hid_t f) {
                              H5Ldelete(f, "/entry_1/data_1", H5P_DEFAULT);
                              H5Lcreate_external((dir / "fifo.h5").c_str(), "/entry_1/data_1", f, "/entry_1/data_1",
                                                 H5P_DEFAULT, H5P_DEFAULT);
                          })),
                          {k_data, "external link", "/entry_1/data_1"});
    const std::string other = (dir / "other.h5").string();
    write_observations_file(other, good);
    expect_refused_naming(read(hostile([&](hid_t f) {
                              H5Ldelete(f, k_x, H5P_DEFAULT);
                              H5Lcreate_external(other.c_str(), k_x, f, k_x, H5P_DEFAULT, H5P_DEFAULT);
                          })),
                          {k_x, "external link"});
    expect_refused_naming(read(hostile([&](hid_t f) {
                              H5Ldelete(f, k_x, H5P_DEFAULT);
                              H5Lcreate_soft("/entry_1/wavebrdf_1/y_um", f, k_x, H5P_DEFAULT, H5P_DEFAULT);
                          })),
                          {k_x, "soft or user link"});
    // A virtual dataset whose source file is missing (HDF5 would give all-zero slices).
    expect_refused_naming(read(hostile([&](hid_t f) {
                              const hsize_t dims[4] = {4, 1, 8, 8};
                              const hid_t space = H5Screate_simple(4, dims, nullptr);
                              const hid_t dcpl = H5Pcreate(H5P_DATASET_CREATE);
                              H5Pset_virtual(dcpl, space, (dir / "missing.h5").c_str(), k_data, space);
                              replace(f, k_data, H5T_IEEE_F32LE, {4, 1, 8, 8}, dcpl);
                              H5Pclose(dcpl);
                              H5Sclose(space);
                          })),
                          {k_data, "virtual dataset"});
}

// One changed byte in the slices' layout message: a chunk dimension 8 → 8 + 2^19 (under the
// chunk-size bound) made H5Dread read out of bounds (a segfault). Refused before any read.
TEST(HostileInputTest, Hdf5CorruptChunkDimensionIsRefusedBeforeReading) {
    const fs::path dir = fresh_dir("hostile");
    const fs::path path = dir / "flip.h5";
    write_observations_file(path.string(), small_set(8));
    std::string bytes = read_text(path);
    // The layout message's chunk dims (1, 1, 8, 8) and element size 4, 32-bit little endian.
    const std::string dims("\x01\0\0\0\x01\0\0\0\x08\0\0\0\x08\0\0\0\x04\0\0\0", 20);
    const std::size_t at = bytes.find(dims);
    ASSERT_NE(at, std::string::npos) << "the chunk dims were not found in the file";
    ASSERT_EQ(bytes.find(dims, at + 1), std::string::npos) << "the chunk dims are ambiguous";
    bytes[at + 10] = char(bytes[at + 10] | 0x08);  // 8 → 524296
    std::ofstream(path, std::ios::binary) << bytes;
    expect_refused_naming(message_of_read_in_child(dir, [&] { read_observations_file(path.string()); }),
                          {k_data, "chunk dimension 524296", "axis 2"});
}

TEST(HostileInputTest, Hdf5DeclaredButUnwrittenChunksAndMissingFiltersAreNamed) {
    const fs::path dir = fresh_dir("hostile");
    const fs::path path = dir / "chunks.h5";
    write_observations_file(path.string(), small_set(4));
    // 1e8 observations in chunks of one slice, none written, in a file of a few kilobytes.
    edit_file(path, [](hid_t f) {
        const hid_t dcpl = H5Pcreate(H5P_DATASET_CREATE);
        const hsize_t chunk[4] = {1, 1, 4, 4};
        H5Pset_chunk(dcpl, 4, chunk);
        replace(f, k_data, H5T_IEEE_F32LE, {100000000, 1, 4, 4}, dcpl);
        // The index too, chunked and never written (contiguous ones are bounded by their bytes).
        const hid_t one = H5Pcreate(H5P_DATASET_CREATE);
        const hsize_t chunk1[1] = {1}, chunk2[2] = {1, 1};
        H5Pset_chunk(one, 1, chunk1);
        replace(f, k_x, H5T_IEEE_F64LE, {100000000}, one);
        const hid_t two = H5Pcreate(H5P_DATASET_CREATE);
        H5Pset_chunk(two, 2, chunk2);
        replace(f, "/entry_1/wavebrdf_1/wavelengths_um", H5T_IEEE_F64LE, {100000000, 1}, two);
        H5Pclose(one);
        H5Pclose(two);
        H5Pclose(dcpl);
    });
    EXPECT_LT(fs::file_size(path), 100000u);
    expect_refused_naming(message_of_read_in_child(dir, [&] { read_observations_file(path.string(), 0, 1, 100.0); }),
                          {k_x, "holds 0 of its 100000000 chunks", "never written"});
    // The slices compressed with a filter this HDF5 lacks (lzf, h5py's own, id 32000).
    write_observations_file(path.string(), small_set(4));
    edit_file(path, [](hid_t f) {
        const hid_t dcpl = H5Pcreate(H5P_DATASET_CREATE);
        const hsize_t chunk[4] = {1, 1, 4, 4};
        H5Pset_chunk(dcpl, 4, chunk);
        ASSERT_GE(H5Pset_filter(dcpl, 32000, H5Z_FLAG_OPTIONAL, 0, nullptr), 0);
        std::vector<double> values(4 * 16, 0.5);
        replace(f, k_data, H5T_IEEE_F32LE, {4, 1, 4, 4}, dcpl, values);
        H5Pclose(dcpl);
    });
    expect_refused_naming(message_of_read_in_child(dir, [&] { read_observations_file(path.string()); }),
                          {k_data, "filter 32000", "does not have"});
}

// h5py's default for a string attribute is a variable-length UTF-8 string: read as the docs say.
TEST(HostileInputTest, Hdf5VariableLengthUtf8AttributeIsRead) {
    const fs::path dir = fresh_dir("hostile");
    const fs::path path = dir / "utf8.h5";
    const std::vector<Observation> good = small_set(4);
    write_observations_file(path.string(), good);
    edit_file(path, [](hid_t f) {
        H5Adelete(f, "wavebrdf_format");
        const hid_t type = H5Tcopy(H5T_C_S1);
        H5Tset_size(type, H5T_VARIABLE);
        H5Tset_cset(type, H5T_CSET_UTF8);
        const hid_t space = H5Screate(H5S_SCALAR);
        const hid_t attribute = H5Acreate2(f, "wavebrdf_format", type, space, H5P_DEFAULT, H5P_DEFAULT);
        const char* text = "wavebrdf_observations 1";
        ASSERT_GE(H5Awrite(attribute, type, &text), 0);
        H5Aclose(attribute);
        H5Sclose(space);
        H5Tclose(type);
    });
    const std::vector<Observation> read = read_observations_file(path.string());
    ASSERT_EQ(read.size(), good.size());
    EXPECT_EQ(read[3].reference, good[3].reference);
}

#endif
