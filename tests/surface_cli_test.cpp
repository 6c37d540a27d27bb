// The commands' unit check (docs/model.md, "Where the model holds"): every command that reads
// or makes a heightfield prints its rms height, rms slope and phase rms, and warns when the
// heights look like nm or m read as µm.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include "cli_util.h"
#include "wavebrdf/heightfield.h"
#include "wavebrdf/io.h"

namespace fs = std::filesystem;
using namespace wavebrdf::test;

namespace {

// A 32 × 32 Gaussian-noise heightfield of rms `rms` in the file's values, texel 1 µm, vscale 1.
void write_noise(const fs::path& path, double rms) {
    std::mt19937 rng(2);
    std::normal_distribution<double> normal(0.0, rms);
    std::vector<double> v(32 * 32);
    for (double& x : v) x = normal(rng);
    wavebrdf::write_heightfield_exr(path.string(), wavebrdf::Heightfield(32, 32, v, 1.0, 1.0), "test");
}

bool contains(const std::string& text, const std::string& needle) { return text.find(needle) != std::string::npos; }

}  // namespace

TEST(SurfaceCli, RenderWarnsOnHeightsInNanometres) {
    const fs::path dir = fresh_dir("surface_cli");
    write_noise(dir / "nm.exr", 50.0);  // 50 nm rms written as if µm
    const CliResult r = run_cli(dir, "render --heightfield nm.exr --resolution 8 --sigma-p-um 4 --x-um 16 "
                                     "--y-um 16 --out o.exr --quiet");
    EXPECT_EQ(r.exit_code, 0) << r.err;
    EXPECT_TRUE(contains(r.err, "wavebrdf: warning: nm.exr: rms slope")) << r.err;
    EXPECT_TRUE(contains(r.err, "heights are in nm")) << r.err;
    // The same surface in µm: the summary line, no warning.
    write_noise(dir / "um.exr", 0.05);
    const CliResult ok = run_cli(dir, "render --heightfield um.exr --resolution 8 --sigma-p-um 4 --x-um 16 "
                                      "--y-um 16 --out o2.exr");
    EXPECT_EQ(ok.exit_code, 0) << ok.err;
    EXPECT_TRUE(contains(ok.err, "um.exr: rms height")) << ok.err;
    EXPECT_TRUE(contains(ok.err, "phase rms")) << ok.err;
    EXPECT_FALSE(contains(ok.err, "warning")) << ok.err;
}

TEST(SurfaceCli, GenbrdfTableAndHeightfieldPrintTheUnitCheck) {
    const fs::path dir = fresh_dir("surface_cli");
    write_noise(dir / "nm.exr", 50.0);
    const CliResult g = run_cli(dir, "genbrdf -i nm.exr -o g.exr -r 8 -l 0.5 -x 16 -y 16 -p 4 --quiet");
    EXPECT_EQ(g.exit_code, 0) << g.err;
    EXPECT_TRUE(contains(g.err, "warning: nm.exr: rms slope")) << g.err;
    const CliResult t = run_cli(dir, "table --heightfield nm.exr --lights 2x2 --resolution 8 --sigma-p-um 4 --x-um 16 "
                                     "--y-um 16 --out t.exr --quiet");
    EXPECT_TRUE(contains(t.err, "warning: nm.exr: rms slope")) << t.err;
    const CliResult h = run_cli(dir, "heightfield --size 32 --out h.exr --no-png --texel-um 0.5");
    EXPECT_EQ(h.exit_code, 0) << h.err;
    EXPECT_TRUE(contains(h.err, "h.exr: rms height")) << h.err;
}
