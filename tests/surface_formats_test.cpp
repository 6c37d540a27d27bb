// The binary surface formats against files other programs wrote: the real scans in
// ../shared/real-surfaces/ (an instrument's or MountainsMap's own files, with values published
// by SurfaceTopography and SOURCES.md), Gwyddion's reading of the same files and of the files we
// write, and the files Gwyddion writes; then each format's refusals.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>

#include "test_util.h"
#include "wavebrdf/observation_file.h"
#include "wavebrdf/surface_file.h"

namespace wavebrdf {
namespace {

namespace fs = std::filesystem;
using test::expect_throw_naming;

// ../shared/real-surfaces/ beside the clone (CI puts it there); a test that needs it fails under CI when it is
// missing and is skipped with a message elsewhere.
// (A git worktree under a folder of worktrees finds it one level further up.)
const fs::path k_shared = fs::exists(fs::path(WAVEBRDF_SOURCE_DIR) / ".." / "shared")
                              ? fs::path(WAVEBRDF_SOURCE_DIR) / ".." / "shared"
                              : fs::path(WAVEBRDF_SOURCE_DIR) / ".." / ".." / "shared";

bool in_ci() { return std::getenv("CI") != nullptr; }

#define REQUIRE_FILE(path)                                                                        \
    do {                                                                                          \
        if (!fs::exists(path)) {                                                                  \
            if (in_ci()) FAIL() << (path) << " is missing (CI must have ../shared/real-surfaces)"; \
            GTEST_SKIP() << (path) << " is missing: the real-surface checks did not run";         \
        }                                                                                         \
    } while (0)

struct Moments {
    double mean = 0, rms = 0, min = 1e300, max = -1e300;
    std::size_t valid = 0;
};

Moments moments(const MeasuredSurface& s) {
    Moments m;
    double sum = 0;
    for (double h : s.heights_um)
        if (!std::isnan(h)) sum += h, ++m.valid, m.min = std::min(m.min, h), m.max = std::max(m.max, h);
    m.mean = sum / double(m.valid);
    double sq = 0;
    for (double h : s.heights_um)
        if (!std::isnan(h)) sq += (h - m.mean) * (h - m.mean);
    m.rms = std::sqrt(sq / double(m.valid));
    return m;
}

// What Gwyddion read (tests/gwyddion/gwy_probe.c): "key value" lines; empty when it failed.
std::map<std::string, std::string> gwyddion_probe(const std::string& in, const std::string& out = "") {
    std::map<std::string, std::string> result;
#ifdef WAVEBRDF_GWY_PROBE
    // Paths are the tests' own (temporary files, ../shared/real-surfaces), quoted; no user input reaches here.
    const std::string command = std::string("'") + WAVEBRDF_GWY_PROBE + "' '" + in + "'" + (out.empty() ? "" : " '" + out + "'");
    FILE* pipe = ::popen(command.c_str(), "r");
    if (!pipe) return result;
    char line[512];
    while (std::fgets(line, sizeof line, pipe)) {
        std::string text(line);
        const std::size_t space = text.find(' ');
        if (space == std::string::npos) continue;
        std::string value = text.substr(space + 1);
        while (!value.empty() && (value.back() == '\n' || value.back() == '\r')) value.pop_back();
        result[text.substr(0, space)] = value;
    }
    if (::pclose(pipe) != 0) result.clear();
#else
    (void)in;
    (void)out;
#endif
    return result;
}

#define REQUIRE_GWYDDION()                                                                          \
    do {                                                                                            \
        if (!have_gwyddion()) {                                                                     \
            if (in_ci()) FAIL() << "built without Gwyddion (tests/gwyddion/gwy_probe.c); CI has it"; \
            GTEST_SKIP() << "built without Gwyddion (libgwyddion20-dev): the Gwyddion checks did not run"; \
        }                                                                                           \
    } while (0)

bool have_gwyddion() {
#ifdef WAVEBRDF_GWY_PROBE
    return true;
#else
    return false;
#endif
}

double number(const std::map<std::string, std::string>& probe, const std::string& key) {
    const auto it = probe.find(key);
    if (it == probe.end()) {
        ADD_FAILURE() << "Gwyddion reported no " << key;
        return std::nan("");
    }
    return std::stod(it->second);
}

// Our reading of `path` agrees with Gwyddion's: size, physical size, the corners, the moments.
// `gwyddion_masks`: false for SUR, whose zmin − 2 marker Gwyddion 2.62 keeps as a height (we
// read it as not measured, as SurfaceTopography does): then the masked points' count and the
// moments are not compared.
void expect_same_as_gwyddion(const std::string& path, const MeasuredSurface& s, double rel, bool gwyddion_masks = true) {
    const auto g = gwyddion_probe(path);
    ASSERT_FALSE(g.empty()) << "Gwyddion cannot read " << path;
    EXPECT_EQ(number(g, "xres"), s.cols);
    EXPECT_EQ(number(g, "yres"), s.rows);
    EXPECT_NEAR(number(g, "xreal") * 1e6, s.cols * s.dx_um, 1e-6 * s.cols * s.dx_um);
    EXPECT_NEAR(number(g, "yreal") * 1e6, s.rows * s.dy_um, 1e-6 * s.rows * s.dy_um);
    const Moments m = moments(s);
    const double scale = std::max(m.max - m.min, 1e-300);
    const std::size_t last = s.heights_um.size() - 1;
    for (const auto& [key, index] : std::map<std::string, std::size_t>{
             {"z00", 0}, {"z01", 1}, {"z10", std::size_t(s.cols)}, {"zlast", last}})
        if (!std::isnan(s.heights_um[index])) {
            EXPECT_NEAR(number(g, key) * 1e6, s.heights_um[index], rel * scale) << key;
        }
    if (!gwyddion_masks) return;
    EXPECT_EQ(number(g, "masked"), double(s.invalid_count()));
    if (s.invalid_count() == 0) {
        EXPECT_NEAR(number(g, "rms") * 1e6, m.rms, rel * m.rms);
        EXPECT_NEAR(number(g, "min") * 1e6, m.min, rel * scale);
        EXPECT_NEAR(number(g, "max") * 1e6, m.max, rel * scale);
    }
}

std::string temp_file(const std::string& name) {
    const fs::path dir = fs::path(WAVEBRDF_TEST_TMP) / "surface_formats" / std::to_string(::getpid());
    fs::create_directories(dir);
    return (dir / name).string();
}

// A surface with structure along both axes, non-square spacing and two points not measured.
MeasuredSurface synthetic(bool with_nan) {
    MeasuredSurface s;
    s.rows = 24;
    s.cols = 37;
    s.dx_um = 0.25;
    s.dy_um = 0.4;
    s.format = "test";
    for (int r = 0; r < s.rows; ++r)
        for (int c = 0; c < s.cols; ++c)
            s.heights_um.push_back(0.3 * std::sin(0.37 * c) + 0.05 * r - 0.002 * c * r + 1e-3 * ((r * 7 + c * 3) % 5));
    if (with_nan) {
        s.heights_um[5 * 37 + 7] = std::nan("");
        s.heights_um[20 * 37 + 30] = std::nan("");
    }
    s.metadata.push_back({"source", "surface_formats_test <synthetic> & \"quoted\""});
    return s;
}

// ---------------------------------------------------------------------------------------------

TEST(SurfaceFileShared, BulletLandX3pInAFolderWithNaN) {
    const fs::path path = k_shared / "real-surfaces" / "x3ptools__sample-land.x3p";
    REQUIRE_FILE(path);
    const MeasuredSurface s = read_surface(path.string());
    EXPECT_EQ(s.format, "x3p");
    EXPECT_EQ(s.cols, 918);
    EXPECT_EQ(s.rows, 256);
    EXPECT_NEAR(s.dx_um, 2.58, 1e-9);
    EXPECT_NEAR(s.dy_um, 2.58, 1e-9);
    const Moments m = moments(s);
    EXPECT_NEAR(m.min, -79.5, 0.05);
    EXPECT_NEAR(m.max, 52.5, 0.05);
    EXPECT_NEAR(100.0 * double(s.invalid_count()) / double(s.heights_um.size()), 10.76, 0.005);
    EXPECT_EQ(s.meta("main_xml_md5"), "ok");
    EXPECT_NE(s.meta("instrument").find("Sensofar"), std::string::npos);
    EXPECT_NE(s.meta("mask"), "");
    // The model refuses it as it is: NaN.
    expect_throw_naming<std::invalid_argument>([&] { to_heightfield(s, path.string()); }, "not measured (NaN)");
}

TEST(SurfaceFileShared, MountainsMapX3pNonSquareMatchesPublishedAndGwyddion) {
    const fs::path path = k_shared / "real-surfaces" / "SurfaceTopography__x3p-2.x3p";
    REQUIRE_FILE(path);
    const MeasuredSurface s = read_surface(path.string());
    EXPECT_EQ(s.cols, 650);
    EXPECT_EQ(s.rows, 650);
    EXPECT_NEAR(s.dx_um, 0.12766, 5e-6);
    EXPECT_NEAR(s.dy_um, 0.31458, 5e-6);
    // SurfaceTopography's test_x3p.py: rms height 7.728033e-8 m.
    EXPECT_NEAR(moments(s).rms, 7.728033e-2, 1e-7);
    expect_throw_naming<std::invalid_argument>([&] { to_heightfield(s, path.string()); }, "is not square");
    REQUIRE_GWYDDION();
    expect_same_as_gwyddion(path.string(), s, 1e-12);
}

TEST(SurfaceFileShared, SensofarPluMatchesPublishedAndGwyddion) {
    const fs::path path = k_shared / "real-surfaces" / "SurfaceTopography__plu-1.plu";
    REQUIRE_FILE(path);
    const MeasuredSurface s = read_surface(path.string());
    EXPECT_EQ(s.format, "plu");
    EXPECT_EQ(s.cols, 768);
    EXPECT_EQ(s.rows, 576);
    EXPECT_NEAR(s.dx_um, 1.66, 1e-6);
    EXPECT_NEAR(s.dy_um, 1.66, 1e-6);
    const Moments m = moments(s);
    // SurfaceTopography's test_plu.py: rms 2.834391 µm; SOURCES.md: −111.2 … −101.2 µm.
    EXPECT_NEAR(m.rms, 2.834391, 2e-6);
    EXPECT_NEAR(m.min, -111.2, 0.05);
    EXPECT_NEAR(m.max, -101.2, 0.05);
    // Square and complete: the model takes it (transposed, heights kept in µm).
    const Heightfield hf = to_heightfield(s, path.string());
    EXPECT_EQ(hf.rows(), 768);
    EXPECT_NEAR(hf.height_um(5, 3), s.heights_um[3 * 768 + 5], 1e-9);
    REQUIRE_GWYDDION();
    expect_same_as_gwyddion(path.string(), s, 1e-6);
}

TEST(SurfaceFileShared, DigitalSurfSurCountsItsNonMeasuredPoints) {
    const fs::path path = k_shared / "real-surfaces" / "SurfaceTopography__sur-2.sur";
    REQUIRE_FILE(path);
    const MeasuredSurface s = read_surface(path.string());
    EXPECT_EQ(s.format, "sur");
    EXPECT_EQ(s.cols, 563);
    EXPECT_EQ(s.rows, 484);
    EXPECT_NEAR(s.dx_um, 3.484, 1e-6);
    EXPECT_NEAR(s.dy_um, 3.484, 1e-6);
    EXPECT_EQ(s.invalid_count(), 117u);  // SurfaceTopography's test_sur.py
    const Moments m = moments(s);
    EXPECT_NEAR(m.min, 8.91, 0.005);
    EXPECT_NEAR(m.max, 10.39, 0.005);
    REQUIRE_GWYDDION();
    expect_same_as_gwyddion(path.string(), s, 1e-6, false);
}

// ---------------------------------------------------------------------------------------------

TEST(SurfaceFileGwyddion, ReadsTheX3pAndSdfWeWrite) {
    REQUIRE_GWYDDION();
    for (bool with_nan : {false, true}) {
        const MeasuredSurface s = synthetic(with_nan);
        for (const char* ext : {".x3p", ".sdf"}) {
            const std::string path = temp_file(std::string("ours") + (with_nan ? "_nan" : "") + ext);
            write_surface(path, s);
            SCOPED_TRACE(path);
            expect_same_as_gwyddion(path, s, 1e-12);
            // And we read it back exactly.
            const MeasuredSurface back = read_surface(path);
            ASSERT_EQ(back.heights_um.size(), s.heights_um.size());
            for (std::size_t i = 0; i < s.heights_um.size(); ++i) {
                if (std::isnan(s.heights_um[i])) EXPECT_TRUE(std::isnan(back.heights_um[i]));
                else EXPECT_NEAR(back.heights_um[i], s.heights_um[i], 1e-15);
            }
            EXPECT_NEAR(back.dx_um, s.dx_um, 1e-15);
            EXPECT_NEAR(back.dy_um, s.dy_um, 1e-15);
        }
    }
}

TEST(SurfaceFileGwyddion, ReadsTheSdfSurAndTextGwyddionWrites) {
    REQUIRE_GWYDDION();
    const MeasuredSurface s = synthetic(false);
    const std::string ours = temp_file("source.x3p");
    write_surface(ours, s);
    const Moments m = moments(s);
    // Gwyddion's exports: SDF as text with 6 significant digits ("aBCR-0.0"), SUR as int32
    // counts of the range, the ASCII matrix with 5 significant digits (no spacing: given).
    for (const auto& [ext, rel] : std::map<std::string, double>{{".sdf", 1e-5}, {".sur", 1e-6}, {".txt", 1e-4}}) {
        const std::string path = temp_file("gwyddion" + ext);
        ASSERT_FALSE(gwyddion_probe(ours, path).empty()) << "Gwyddion cannot write " << path;
        SCOPED_TRACE(path);
        const MeasuredSurface g = read_surface(path, s.dx_um);
        ASSERT_EQ(g.rows, s.rows);
        ASSERT_EQ(g.cols, s.cols);
        if (ext != ".txt") {
            EXPECT_NEAR(g.dx_um, s.dx_um, 1e-5 * s.dx_um);
            EXPECT_NEAR(g.dy_um, s.dy_um, 1e-5 * s.dy_um);
        }
        double worst = 0;
        for (std::size_t i = 0; i < s.heights_um.size(); ++i)
            worst = std::max(worst, std::abs(g.heights_um[i] - (ext == ".txt" ? s.heights_um[i] * 1e-6 : s.heights_um[i])));
        // The text matrix holds metres (no header saying so): compared in metres.
        EXPECT_LT(worst, rel * (ext == ".txt" ? 1e-6 : 1.0) * (m.max - m.min + std::abs(m.max)));
    }
}

// The fuzzers' seeds (fuzz/corpus/surface_<format>/, hand-made from the layouts in
// docs/surfaces.md): each is accepted by the reader it seeds, and, for the binary formats,
// Gwyddion's own reader sees the same surface in it.
const char* const k_seed_formats[] = {"x3p", "sdf", "plu", "sur", "al3d", "metropro", "npy", "text", "datx"};

TEST(SurfaceFileSeeds, EverySeedReadsAsItsFormat) {
    for (const char* format : k_seed_formats) {
        if (std::string(format) == "datx" && !built_with_hdf5()) continue;  // read by the HDF5 plugin
        const fs::path dir = fs::path(WAVEBRDF_SOURCE_DIR) / "fuzz" / "corpus" / (std::string("surface_") + format);
        int count = 0;
        for (const auto& entry : fs::directory_iterator(dir)) {
            std::ifstream in(entry.path(), std::ios::binary);
            const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
            EXPECT_EQ(detect_surface_format(bytes), format) << entry.path();
            const MeasuredSurface s = read_surface_as(bytes, format, entry.path().string(), 0.5);
            EXPECT_GE(s.rows, 2) << entry.path();
            ++count;
        }
        EXPECT_GE(count, 1) << dir;
    }
}

TEST(SurfaceFileGwyddion, SeesTheSameSurfaceInEveryBinarySeed) {
    REQUIRE_GWYDDION();
    for (const char* format : {"x3p", "sdf", "plu", "sur", "al3d", "metropro"}) {
        const fs::path dir = fs::path(WAVEBRDF_SOURCE_DIR) / "fuzz" / "corpus" / (std::string("surface_") + format);
        for (const auto& entry : fs::directory_iterator(dir)) {
            SCOPED_TRACE(entry.path().string());
            const MeasuredSurface s = read_surface(entry.path().string());
            expect_same_as_gwyddion(entry.path().string(), s, 1e-6, std::string(format) != "sur");
        }
    }
}

// ---------------------------------------------------------------------------------------------

TEST(SurfaceFileX3p, RefusesDamageAndUnsupportedVariants) {
    const MeasuredSurface s = synthetic(false);
    const std::string path = temp_file("good.x3p");
    write_surface(path, s);
    std::ifstream in(path, std::ios::binary);
    const std::string good((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    EXPECT_EQ(read_surface_bytes(good, "good.x3p").rows, 24);
    expect_throw_naming<std::runtime_error>([&] { read_surface_bytes(good.substr(0, good.size() / 2), "half.x3p"); },
                                            "half.x3p");
    expect_throw_naming<std::runtime_error>([&] { read_surface_as(std::string("PK\x03\x04junk", 8), "x3p", "j.x3p"); },
                                            "j.x3p");
    EXPECT_EQ(detect_surface_format(good), "x3p");
}

TEST(SurfaceFileSdf, ReadsTheStandardsAsciiExampleAndRefusesDamage) {
    // The ASCII example of ISO 25178-71 as SurfaceTopography keeps it (sdf-1.sdf), with its trailer.
    const std::string ascii =
        "aISO-1.0\nManufacID = ISOTC213\nCreateDate = 040120100853\nModDate = 050320101353\nNumPoints = 7\n"
        "NumProfiles = 4\nXscale = 1.0E-6\nYscale = 1.0E-6\nZscale = 1.0E-6\nZresolution = 1.0E-9\nCompression = 0\n"
        "DataType = 7\nCheckType = 0\n*\n1.00000 0.99874 0.99495 0.98865 0.97986 0.96858 1.00000\n"
        "0.99874 0.99748 0.99369 0.98740 0.97862 0.96736 0.99874\n0.99495 0.99369 0.98993 0.98366 0.97491 0.96369 0.99495\n"
        "0.97986 0.97862 0.97491 0.96874 0.96012 0.94907 0.97986\n*\n< OperatorName > Tom Jones < / OperatorName >\n";
    const MeasuredSurface s = read_surface_bytes(ascii, "sdf-1.sdf");
    EXPECT_EQ(s.format, "sdf");
    EXPECT_EQ(s.cols, 7);
    EXPECT_EQ(s.rows, 4);
    EXPECT_NEAR(s.dx_um, 1.0, 1e-12);
    EXPECT_NEAR(s.heights_um[7 + 1], 0.99748, 1e-12);
    EXPECT_NEAR(s.heights_um[27], 0.97986, 1e-12);
    EXPECT_EQ(s.meta("instrument"), "ISOTC213");
    std::string bad = ascii;
    bad.replace(bad.find("0.99748"), 7, "0.9x748");
    expect_throw_naming<std::runtime_error>([&] { read_surface_bytes(bad, "b.sdf"); }, "expected a number or BAD");
    std::string big = ascii;
    big.replace(big.find("NumPoints = 7"), 13, "NumPoints = 60000");
    expect_throw_naming<std::runtime_error>([&] { read_surface_bytes(big, "b.sdf"); }, "truncated");
    std::string compressed = ascii;
    compressed.replace(compressed.find("Compression = 0"), 15, "Compression = 1");
    expect_throw_naming<std::runtime_error>([&] { read_surface_bytes(compressed, "c.sdf"); }, "compressed");
    std::string huge_code = ascii;
    huge_code.replace(huge_code.find("DataType = 7"), 12, "DataType = 1e300");
    expect_throw_naming<std::runtime_error>([&] { read_surface_bytes(huge_code, "h.sdf"); }, "expected a code 0 to 255");
    // Binary: what we write reads back; a short file is truncated.
    const std::string path = temp_file("b.sdf");
    write_surface(path, synthetic(true));
    std::ifstream in(path, std::ios::binary);
    const std::string binary((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    EXPECT_EQ(read_surface_bytes(binary, "b.sdf").invalid_count(), 2u);
    expect_throw_naming<std::runtime_error>([&] { read_surface_bytes(binary.substr(0, 200), "b.sdf"); }, "truncated");
}

TEST(SurfaceFileAl3d, HugeDeclaredSizesAreRefusedBeforeUse) {
    const fs::path seed = fs::path(WAVEBRDF_SOURCE_DIR) / "fuzz" / "corpus" / "surface_al3d" / "tiny.al3d";
    std::ifstream in(seed, std::ios::binary);
    const std::string good((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    ASSERT_EQ(read_surface_bytes(good, "a.al3d").rows, 3);
    for (const char* rows : {"1e300", "-7", "70000", "2.5"}) {
        std::string bad = good;
        const std::size_t at = bad.find("Rows");
        ASSERT_NE(at, std::string::npos);
        std::string value(30, '\0');
        value.replace(0, std::strlen(rows), rows);
        bad.replace(at + 20, 30, value);
        expect_throw_naming<std::runtime_error>([&] { read_surface_bytes(bad, "a.al3d"); }, "AL3D Cols");
    }
}

TEST(SurfaceFileBinary, TruncatedRealFilesAreRefusedNotOverread) {
    // Every prefix length class of the shared files: header cut, data cut.
    for (const char* name : {"SurfaceTopography__plu-1.plu", "SurfaceTopography__sur-2.sur"}) {
        const fs::path path = k_shared / "real-surfaces" / name;
        if (!fs::exists(path)) continue;
        std::ifstream in(path, std::ios::binary);
        const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
        const std::string format = detect_surface_format(bytes);
        for (std::size_t cut : {std::size_t(20), std::size_t(300), std::size_t(520), bytes.size() / 3})
            expect_throw_naming<std::runtime_error>([&] { read_surface_as(bytes.substr(0, cut), format, name); }, name);
    }
}

// ---------------------------------------------------------------------------------------------
// Instrument files fetched from SurfaceTopography into ../shared/format-examples/ (SOURCES.md
// there); optional: skipped with a message where that folder is missing.

#define REQUIRE_EXAMPLE(path) \
    do {                      \
        if (!fs::exists(path)) GTEST_SKIP() << (path) << " is missing: this format's instrument file was not checked"; \
    } while (0)

TEST(SurfaceFileExamples, AliconaAl3dMatchesPublishedAndGwyddion) {
    const fs::path path = k_shared / "format-examples" / "SurfaceTopography__al3d-1.al3d";
    REQUIRE_EXAMPLE(path);
    const MeasuredSurface s = read_surface(path.string());
    EXPECT_EQ(s.format, "al3d");
    EXPECT_EQ(s.cols, 200);
    EXPECT_EQ(s.rows, 296);
    EXPECT_NEAR(s.cols * s.dx_um, 87.6054, 1e-4);
    EXPECT_NEAR(s.rows * s.dy_um, 129.655992, 1e-4);
    // SurfaceTopography: 7.688266102603082e-06 m (their rtol 1e-6; Gwyddion's is 7.68829e-06).
    EXPECT_NEAR(moments(s).rms, 7.688266102603082, 1e-6 * 7.69);
    // Heights of 76 mm ± 20 µm: Gwyddion's rms (7.6882887 µm) is 3e-6 off SurfaceTopography's
    // and ours; the sizes and values themselves agree exactly.
    if (have_gwyddion()) expect_same_as_gwyddion(path.string(), s, 1e-5);
}

TEST(SurfaceFileExamples, ZygoMetroProMatchesPublishedAndGwyddion) {
    const fs::path path = k_shared / "format-examples" / "SurfaceTopography__metropro-1.dat";
    REQUIRE_EXAMPLE(path);
    const MeasuredSurface s = read_surface(path.string());
    EXPECT_EQ(s.format, "metropro");
    EXPECT_EQ(s.cols, 640);
    EXPECT_EQ(s.rows, 480);
    EXPECT_NEAR(s.cols * s.dx_um, 702.8812979115173, 1e-6 * 702.9);
    EXPECT_NEAR(s.rows * s.dy_um, 527.160973433638, 1e-6 * 527.2);
    EXPECT_NEAR(moments(s).rms, 7.528822204734589e-2, 1e-6 * 7.53e-2);
    if (have_gwyddion()) expect_same_as_gwyddion(path.string(), s, 1e-6);
}

// A SUR file in metres (MountainsMap): SurfaceTopography's test_sur3_metadata publishes its grid,
// physical size and rms height about the mean. Its header sets the special-points flag and 233 009
// of its 262 144 counts hold zmin − 2 (= −2), which the format reserves for points not measured:
// read as NaN here, while SurfaceTopography and Gwyddion 2.62 take them as heights (a floor just
// below the lowest measured point). With that floor put back, the published rms is reproduced,
// so the grid, scale and offset are read as they read them.
TEST(SurfaceFileExamples, DigitalSurfSur3MatchesPublished) {
    const fs::path path = k_shared / "format-examples" / "SurfaceTopography__sur-3.sur";
    REQUIRE_EXAMPLE(path);
    const MeasuredSurface s = read_surface(path.string());
    EXPECT_EQ(s.format, "sur");
    EXPECT_EQ(s.cols, 512);
    EXPECT_EQ(s.rows, 512);
    EXPECT_NEAR(s.cols * s.dx_um, 0.151319552e6, 1e-6 * 0.1513e6);
    EXPECT_NEAR(s.rows * s.dy_um, 0.151319552e6, 1e-6 * 0.1513e6);
    EXPECT_EQ(s.invalid_count(), 233009u);
    // The measured counts run from zmin 0 to zmax 6 992 350 (the header): one count in µm.
    const Moments measured = moments(s);
    const double count_um = (measured.max - measured.min) / 6992350.0;
    MeasuredSurface floor = s;
    for (double& h : floor.heights_um)
        if (std::isnan(h)) h = measured.min - 2.0 * count_um;
    EXPECT_NEAR(moments(floor).rms, 0.0019200491394179297e6, 1e-6 * 1920.05);
    if (have_gwyddion()) expect_same_as_gwyddion(path.string(), s, 1e-6, false);
}

TEST(SurfaceFileExamples, IsoSdfAsciiExample) {
    const fs::path path = k_shared / "format-examples" / "SurfaceTopography__sdf-1.sdf";
    REQUIRE_EXAMPLE(path);
    const MeasuredSurface s = read_surface(path.string());
    EXPECT_EQ(s.cols, 7);
    EXPECT_EQ(s.rows, 4);
    EXPECT_NEAR(s.cols * s.dx_um, 7.0, 1e-9);
    if (have_gwyddion()) expect_same_as_gwyddion(path.string(), s, 1e-9);
}

}  // namespace
}  // namespace wavebrdf
