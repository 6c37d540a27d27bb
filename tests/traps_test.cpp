// Traps a new user or a hostile file still found: EXR pixel data bounded by what the file can
// hold, a table read once after its attributes, an inversion's run.json that says whether the
// run finished. Memory is this process's
// peak resident size, reset just before the read, so a test never depends on what other tests
// of this binary allocated (skipped under AddressSanitizer, whose shadow memory inflates it).
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <string>
#include <vector>

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfOutputFile.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "cli_util.h"
#include "test_util.h"
#include "wavebrdf/io.h"
#include "wavebrdf/observation.h"
#include "wavebrdf/table.h"
#include "wavebrdf/version.h"

namespace wavebrdf {
namespace {

namespace fs = std::filesystem;

// A `side` × `side` RGB float EXR of zeros, ZIP-compressed, written from one row of memory (a
// y stride of 0 repeats it), so the test itself never holds the image.
void write_zero_exr(const std::string& path, int side) {
    Imf::Header header(side, side);
    header.compression() = Imf::ZIP_COMPRESSION;
    for (const char* c : {"R", "G", "B"}) header.channels().insert(c, Imf::Channel(Imf::FLOAT));
    std::vector<float> row(std::size_t(side) * 3, 0.0f);
    Imf::OutputFile file(path.c_str(), header);
    Imf::FrameBuffer frame;
    const char* names[3] = {"R", "G", "B"};
    for (int c = 0; c < 3; ++c)
        frame.insert(names[c], Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(row.data() + c), 3 * sizeof(float), 0));
    file.setFrameBuffer(frame);
    file.writePixels(side);
}

long status_kib(const char* field) {
    std::ifstream in("/proc/self/status");
    std::string line;
    while (std::getline(in, line))
        if (line.rfind(field, 0) == 0) return std::atol(line.c_str() + std::strlen(field));
    return -1;
}

struct Measured {
    std::string message;      // the exception's message ("" when `read` returned)
    double grown_bytes = -1;  // peak resident size during `read` minus the size before it
};

// Runs `read` here, with this process's peak resident size reset first (/proc/self/clear_refs;
// a forked child would find OpenEXR's and OpenMP's thread pools without their threads), so the
// peak it reports is what `read` itself made resident: the other threads are idle meanwhile.
Measured measure_read(const std::function<void()>& read) {
    { std::ofstream("/proc/self/clear_refs") << "5"; }
    const long before = status_kib("VmRSS:");
    Measured r;
    EXPECT_LE(status_kib("VmHWM:"), before + 4096) << "the peak resident size was not reset";
    try {
        read();
        r.message = "";
    } catch (const std::exception& e) {
        r.message = e.what();
    }
    r.grown_bytes = double(status_kib("VmHWM:") - before) * 1024.0;
    return r;
}

// Under AddressSanitizer the resident size says little (shadow memory, quarantine): the
// messages are still checked there, the memory in the plain build.
#ifdef WAVEBRDF_ASAN
constexpr bool kMeasuresMemory = false;
#else
constexpr bool kMeasuresMemory = true;
#endif

constexpr int kSide = 2048;                                             // the test images' side
constexpr double kImageBytes = double(kSide) * kSide * 3.0 * sizeof(float);  // 48 MiB as float RGB

// A truncated EXR still declares its whole image: refused from its header, before OpenEXR or the
// reader allocates the declared pixels (a 3 MB table asked for 6.3 GB).
TEST(ExrBound, PixelDataLargerThanTheFileCanHoldIsRefusedBeforeAllocating) {
    const fs::path dir = test::fresh_dir("traps");
    const std::string whole = (dir / "zeros.exr").string(), cut = (dir / "cut.exr").string();
    write_zero_exr(whole, kSide);
    const auto size = fs::file_size(whole);
    ASSERT_LT(double(size) * 1032.0, 4.0 * kImageBytes) << "zeros compress less than the test assumes";
    fs::copy_file(whole, cut);
    fs::resize_file(cut, size / 4);  // the header and the line offsets stay; most chunks are gone
    ASSERT_GT(kImageBytes, 1032.0 * double(size / 4));
    // The whole file is read (a real file at the compression's limit is not refused).
    EXPECT_NO_THROW(read_rgb_exr(whole));
    for (const auto& [what, read] : std::vector<std::pair<std::string, std::function<void()>>>{
             {"read_rgb_exr", [&] { read_rgb_exr(cut); }},
             {"read_heightfield_exr", [&] { read_heightfield_exr(cut); }},
             {"read_brdf_table", [&] { read_brdf_table(cut); }}}) {
        SCOPED_TRACE(what);
        const Measured r = measure_read(read);
        EXPECT_NE(r.message.find("more than its " + std::to_string(size / 4) + " bytes can hold"), std::string::npos)
            << r.message;
        if (kMeasuresMemory) {
            EXPECT_LT(r.grown_bytes, 0.25 * kImageBytes) << "the declared pixels were allocated";
        }
    }
}

// A table file is checked from its attributes before a pixel is allocated, and its values are
// read once into place (before: the whole mosaic, then a second copy of it).
TEST(TableFile, IsReadOnceAndOnlyAfterItsAttributes) {
    const fs::path dir = test::fresh_dir("traps");
    const std::string plain = (dir / "plain.exr").string(), table_path = (dir / "table.exr").string();
    write_zero_exr(plain, kSide);  // an RGB image without a table's attributes
    const Measured refused = measure_read([&] { read_brdf_table(plain); });
    EXPECT_NE(refused.message.find("wavebrdf:kind"), std::string::npos) << refused.message;
    if (kMeasuresMemory) {
        EXPECT_LT(refused.grown_bytes, 0.25 * kImageBytes) << "the pixels were read before the attributes";
    }

    {
        BrdfTable t;
        t.spec.query.sigma_p_um = 3.0;
        t.spec.lambdas_um = {0.5};
        t.spec.resolution = kSide / 8;
        t.spec.lights = {8, 8, 0.8};
        t.heightfield_rows = t.heightfield_cols = 16;
        t.texel_um = 1.0;
        t.version = k_version;
        light_grid_axes(t.spec.lights, t.light_x, t.light_y, t.rendered);
        t.values.assign(std::size_t(kImageBytes / sizeof(float)), 0.0f);
        for (std::size_t k = 0; k < t.values.size(); k += 7) t.values[k] = float(k % 1000) * 1e-3f;
        write_brdf_table(table_path, t);
    }
    const Measured read = measure_read([&] {
        const BrdfTable back = read_brdf_table(table_path);
        if (back.values.size() != std::size_t(kImageBytes / sizeof(float)) || back.values[7] != float(7) * 1e-3f)
            throw std::runtime_error("wrong values");
    });
    EXPECT_EQ(read.message, "");
    std::printf("table of %.0f MiB: the read's peak grew by %.1f MiB\n", kImageBytes / 1048576.0,
                read.grown_bytes / 1048576.0);
    if (kMeasuresMemory) {
        EXPECT_GT(read.grown_bytes, 0.9 * kImageBytes);  // the values themselves are resident
        EXPECT_LT(read.grown_bytes, 1.4 * kImageBytes) << "more than one copy of the table was held";
    }
}

// invert's run.json says "finished": false until every epoch ran and every output was written;
// a run stopped by SIGTERM keeps false, its --resume to the end sets true.
TEST(InvertRunJson, SaysWhetherTheRunFinished) {
    const fs::path dir = test::fresh_dir("traps");
    const std::string small = "invert --size 8 --sigma-p-um 2 --resolution 8 --no-plots --quiet";
    const test::CliResult done = test::run_cli(dir, small + " --epochs 3 --out done");
    ASSERT_EQ(done.exit_code, 0) << done.err;
    EXPECT_EQ(nlohmann::json::parse(test::read_text(dir / "done" / "run.json")).at("finished"), true);

    const std::string start = test::quote(WAVEBRDF_CLI) + " " + small + " --epochs 10000000 --out run";
    const test::CliResult r = test::run_in(
        dir, "{ " + start +
                 " & pid=$!; n=0; while [ ! -f run/checkpoint.json ] && [ $n -lt 3000 ]; do sleep 0.1; n=$((n+1)); "
                 "done; kill -TERM $pid; wait $pid; echo rc=$?; }");
    EXPECT_NE(r.out.find("rc=143"), std::string::npos) << r.out << r.err;
    ASSERT_TRUE(fs::exists(dir / "run" / "run.json"));
    const auto stopped = nlohmann::json::parse(test::read_text(dir / "run" / "run.json"));
    EXPECT_EQ(stopped.at("finished"), false);
    // Resumed to an end it reaches (the checkpoint's epoch is small: a few seconds of epochs).
    const int epoch = nlohmann::json::parse(test::read_text(dir / "run" / "checkpoint.json")).at("epoch").get<int>();
    const test::CliResult resumed =
        test::run_cli(dir, "invert --resume run --epochs " + std::to_string(epoch + 2) + " --no-plots --quiet");
    ASSERT_EQ(resumed.exit_code, 0) << resumed.err;
    EXPECT_EQ(nlohmann::json::parse(test::read_text(dir / "run" / "run.json")).at("finished"), true);
}

}  // namespace
}  // namespace wavebrdf
