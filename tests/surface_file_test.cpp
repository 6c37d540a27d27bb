// Measured surface files: readers checked against files another program wrote (NumPy's
// np.save, Gwyddion, the instruments' own files in ../shared/real-surfaces/), writers against
// readers that are not ours, and the refusals every reader owes hostile input.
#include "wavebrdf/surface_file.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>

#include "test_util.h"
#include "wavebrdf/io.h"

namespace wavebrdf {
namespace {

using test::expect_throw_naming;

std::string from_hex(const std::string& hex) {
    std::string out;
    for (std::size_t i = 0; i + 1 < hex.size(); i += 2) out += static_cast<char>(std::stoi(hex.substr(i, 2), nullptr, 16));
    return out;
}

std::string temp_path(const std::string& name) {
    return (std::filesystem::temp_directory_path() / ("wavebrdf-surface-test-" + std::to_string(::getpid()) + "-" + name))
        .string();
}

// np.save (NumPy 1.24.2) of [[1.5, -2.25, 3.0], [nan, 0.125, 1e-3]] as <f8 C order, >f4 C
// order, <f8 Fortran order, and numpy.lib.format.write_array(version=(2, 0)).
const std::string k_npy_f8_c =
    "934e554d5059010076007b276465736372273a20273c6638272c2027666f727472616e5f6f72646572273a2046616c73652c2027736861"
    "7065273a2028322c2033292c207d2020202020202020202020202020202020202020202020202020202020202020202020202020202020"
    "20202020202020202020202020202020200a000000000000f83f00000000000002c00000000000000840000000000000f87f0000000000"
    "00c03ffca9f1d24d62503f";
const std::string k_npy_f4_be =
    "934e554d5059010076007b276465736372273a20273e6634272c2027666f727472616e5f6f72646572273a2046616c73652c2027736861"
    "7065273a2028322c2033292c207d2020202020202020202020202020202020202020202020202020202020202020202020202020202020"
    "20202020202020202020202020202020200a3fc00000c0100000404000007fc000003e0000003a83126f";
const std::string k_npy_f8_fortran =
    "934e554d5059010076007b276465736372273a20273c6638272c2027666f727472616e5f6f72646572273a20547275652c202773686170"
    "65273a2028322c2033292c207d202020202020202020202020202020202020202020202020202020202020202020202020202020202020"
    "20202020202020202020202020202020200a000000000000f83f000000000000f87f00000000000002c0000000000000c03f0000000000"
    "000840fca9f1d24d62503f";
const std::string k_npy_v2 =
    "934e554d50590200740000007b276465736372273a20273c6638272c2027666f727472616e5f6f72646572273a2046616c73652c202773"
    "68617065273a2028322c2033292c207d202020202020202020202020202020202020202020202020202020202020202020202020202020"
    "20202020202020202020202020202020200a000000000000f83f00000000000002c00000000000000840000000000000f87f0000000000"
    "00c03ffca9f1d24d62503f";

void expect_numpy_matrix(const MeasuredSurface& s, double tolerance) {
    const double expected[6] = {1.5, -2.25, 3.0, std::nan(""), 0.125, 1e-3};
    ASSERT_EQ(s.rows, 2);
    ASSERT_EQ(s.cols, 3);
    ASSERT_EQ(s.heights_um.size(), 6u);
    for (int i = 0; i < 6; ++i) {
        if (std::isnan(expected[i]))
            EXPECT_TRUE(std::isnan(s.heights_um[std::size_t(i)])) << i;
        else
            EXPECT_NEAR(s.heights_um[std::size_t(i)], expected[i], tolerance * std::abs(expected[i])) << i;
    }
    EXPECT_EQ(s.invalid_count(), 1u);
}

TEST(SurfaceFileNpy, ReadsWhatNumpyWrote) {
    for (const auto* hex : {&k_npy_f8_c, &k_npy_f8_fortran, &k_npy_v2}) {
        const MeasuredSurface s = read_surface_bytes(from_hex(*hex), "a.npy", 0.5);
        EXPECT_EQ(s.format, "npy");
        EXPECT_EQ(s.dx_um, 0.5);
        EXPECT_EQ(s.dy_um, 0.5);
        expect_numpy_matrix(s, 0.0);
    }
    // float32, big-endian: the values rounded to float.
    expect_numpy_matrix(read_surface_bytes(from_hex(k_npy_f4_be), "b.npy", 1.0), 1e-7);
}

TEST(SurfaceFileNpy, RefusesWhatItCannotRead) {
    const std::string good = from_hex(k_npy_f8_c);
    expect_throw_naming<std::runtime_error>([&] { read_surface_bytes(good, "a.npy"); }, "states no spacing");
    // Truncated data, a wrong dtype, a 1-D shape, a huge declared shape.
    expect_throw_naming<std::runtime_error>([&] { read_surface_bytes(good.substr(0, good.size() - 1), "a.npy", 1.0); },
                                            "truncated");
    std::string int_dtype = good;
    int_dtype.replace(int_dtype.find("<f8"), 3, "<i8");
    expect_throw_naming<std::runtime_error>([&] { read_surface_bytes(int_dtype, "a.npy", 1.0); }, "'<i8'");
    std::string one_d = good;
    one_d.replace(one_d.find("(2, 3)"), 6, "(6,)  ");
    expect_throw_naming<std::runtime_error>([&] { read_surface_bytes(one_d, "a.npy", 1.0); }, "1-D");
    std::string huge = good;
    huge.replace(huge.find("(2, 3)"), 6, "(9999, 9999)");
    expect_throw_naming<std::runtime_error>([&] { read_surface_bytes(huge, "a.npy", 1.0); }, "truncated");
}

TEST(SurfaceFileNpy, WriterMatchesNumpyBytes) {
    // np.save of a finite C-order float64 array is byte for byte what write_surface makes.
    MeasuredSurface s;
    s.rows = 2;
    s.cols = 3;
    s.dx_um = s.dy_um = 1;
    s.heights_um = {1.5, -2.25, 3.0, std::nan(""), 0.125, 1e-3};
    const std::string path = temp_path("w.npy");
    write_surface(path, s);
    std::ifstream in(path, std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    std::remove(path.c_str());
    EXPECT_EQ(bytes, from_hex(k_npy_f8_c));
}

TEST(SurfaceFileText, ReadsMatricesAndGwyddionHeaders) {
    const MeasuredSurface plain = read_surface_bytes("1.5 -2.25 3\nnan, 0.125; 1e-3\n\n", "m.txt", 2.0);
    EXPECT_EQ(plain.format, "text");
    EXPECT_EQ(plain.dx_um, 2.0);
    expect_numpy_matrix(plain, 0.0);
    // Gwyddion's ASCII export header: 3 columns over 6 µm, 2 rows over 1 mm, heights in m.
    const MeasuredSurface gwy = read_surface_bytes(
        "# Channel: Height\n# Width: 6.000 \xc2\xb5m\n# Height: 1.000 mm\n# Value units: m\n1.5e-6 -2.25e-6 3e-6\nnan "
        "0.125e-6 1e-9\n",
        "g.txt");
    EXPECT_DOUBLE_EQ(gwy.dx_um, 2.0);
    EXPECT_DOUBLE_EQ(gwy.dy_um, 500.0);
    expect_numpy_matrix(gwy, 1e-12);
    expect_throw_naming<std::runtime_error>([] { read_surface_bytes("1 2 3\n4 5\n", "r.txt", 1.0); }, "line 2 has 2 numbers");
    expect_throw_naming<std::runtime_error>([] { read_surface_bytes("1 2 x\n", "r.txt", 1.0); }, "'x' is not a number");
    expect_throw_naming<std::runtime_error>([] { read_surface_bytes("1 2 3\n", "r.txt"); }, "states no spacing");
    expect_throw_naming<std::runtime_error>([] { read_surface_bytes(std::string("\x01\x02\x03zz", 5), "r.bin"); },
                                            "no known surface format");
}

TEST(SurfaceFileHeightfield, TransposesKeepsMicronsAndRefusesWhatNeedsConditioning) {
    MeasuredSurface s;
    s.rows = 2;  // along y
    s.cols = 3;  // along x
    s.dx_um = s.dy_um = 0.5;
    s.heights_um = {0, 1, 2, 10, 11, 12};  // z = c + 10 r
    const Heightfield hf = to_heightfield(s, "s.npy");
    ASSERT_EQ(hf.rows(), 3);  // the heightfield's rows run along x
    ASSERT_EQ(hf.cols(), 2);
    for (int c = 0; c < 3; ++c)
        for (int r = 0; r < 2; ++r) EXPECT_DOUBLE_EQ(hf.height_um(c, r), c + 10 * r);
    EXPECT_EQ(hf.texel_um(), 0.5);
    // Back again: the same surface.
    const MeasuredSurface back = from_heightfield(to_heightfield(s, "s", 0.5, 2.0));
    EXPECT_EQ(back.rows, 2);
    EXPECT_EQ(back.cols, 3);
    for (std::size_t i = 0; i < 6; ++i) EXPECT_DOUBLE_EQ(back.heights_um[i], s.heights_um[i]);

    MeasuredSurface skew = s;
    skew.dy_um = 0.6;
    expect_throw_naming<std::invalid_argument>([&] { to_heightfield(skew, "k.x3p"); }, "--resample-um");
    MeasuredSurface holes = s;
    holes.heights_um[4] = std::nan("");
    expect_throw_naming<std::invalid_argument>([&] { to_heightfield(holes, "h.x3p"); }, "1 of 6 points are not measured");
}

TEST(SurfaceFileHeightfield, HeightfieldReadersTakeMeasuredFiles) {
    // A NumPy file where an EXR heightfield was expected: its spacing from the texel width.
    const std::string path = temp_path("h.npy");
    MeasuredSurface s;
    s.rows = 2;
    s.cols = 3;
    s.dx_um = s.dy_um = 1;
    s.heights_um = {0, 1, 2, 10, 11, 12};
    write_surface(path, s);
    const Heightfield hf = read_heightfield_exr(path, 0.25);
    EXPECT_EQ(hf.rows(), 3);
    EXPECT_EQ(hf.texel_um(), 0.25);
    EXPECT_DOUBLE_EQ(hf.height_um(2, 1), 12.0);
    expect_throw_naming<std::runtime_error>([&] { read_heightfield_exr(path); }, "states no spacing");
    // NaN in it: the one-line advice.
    s.heights_um[0] = std::nan("");
    write_surface(path, s);
    expect_throw_naming<std::invalid_argument>([&] { read_heightfield_exr(path, 1.0); }, "wavebrdf convert");
    // An EXR written from a measured surface reads back as the same surface.
    s.heights_um[0] = 0.0;
    s.dx_um = s.dy_um = 0.75;
    const std::string exr = temp_path("h.exr");
    write_surface(exr, s);
    const MeasuredSurface e = read_surface(exr);
    EXPECT_EQ(e.format, "exr");
    EXPECT_EQ(e.rows, 2);
    EXPECT_EQ(e.cols, 3);
    EXPECT_EQ(e.dx_um, 0.75);
    for (std::size_t i = 0; i < 6; ++i) EXPECT_NEAR(e.heights_um[i], s.heights_um[i], 1e-5 * (1 + s.heights_um[i]));
    std::remove(path.c_str());
    std::remove(exr.c_str());
    expect_throw_naming<std::invalid_argument>([&] { write_surface(temp_path("x.tif"), s); }, ".x3p, .sdf, .npy or .exr");
}

}  // namespace
}  // namespace wavebrdf
