// `wavebrdf recover --simulator`: an unknown simulator fails with one line before any work;
// `scalar` simulates the truth's observations with the scalar-diffraction simulator (run.json
// says so) and the observations it saves are scalar_slice's, not the Gabor model's.
// (The thesis's method with 0 epochs: the recovery is not what is tested, and it is fast.)
#include <gtest/gtest.h>

#include <cmath>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "cli_util.h"
#include "wavebrdf/brdf.h"
#include "wavebrdf/io.h"
#include "wavebrdf/observation.h"
#include "wavebrdf/scalar_diffraction.h"

using namespace wavebrdf;
using namespace wavebrdf::test;

namespace {
const std::string kTiny =
    "--size 8 --texel-um 2 --sigma-p-um 3 --height-range-um 0.1 --seed 5205 --resolution 16 --lambdas-um 0.5 "
    "--method thesis --epochs 0 --no-plots --quiet";
}

TEST(ScalarSimulatorCli, UnknownSimulatorFailsWithOneLine) {
    const fs::path dir = fresh_dir("recover");
    const std::string out = (dir / "out").string();
    expect_one_line_naming(run_cli(dir, "recover --simulator exact --quiet --out " + out), {"--simulator", "exact"});
    EXPECT_FALSE(fs::exists(out) && !fs::is_empty(out));
}

TEST(ScalarSimulatorCli, ScalarObservationsAreTheSimulatorsSlices) {
    const fs::path dir = fresh_dir("recover");
    const CliResult r = run_cli(dir, "recover " + kTiny + " --simulator scalar --save-observations --out run");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const nlohmann::json run = nlohmann::json::parse(read_text(dir / "run" / "run.json"));
    EXPECT_EQ(run.value("simulator", ""), "scalar");
    const Heightfield truth = read_heightfield_exr((dir / "run" / "truth.exr").string());
    const std::vector<Observation> observations = read_observations_json((dir / "run" / "observations.json").string());
    ASSERT_FALSE(observations.empty());
    double to_scalar = 0.0, to_gabor = 0.0, norm = 0.0;
    for (const Observation& o : {observations.front(), observations.back()}) {
        const std::vector<double> s = scalar_slice(truth, o.query, o.lambdas_um[0], o.resolution);
        const std::vector<double> g = render_slice<double>(truth, o.query, o.lambdas_um[0], o.resolution);
        for (std::size_t i = 0; i < s.size(); ++i) {
            const double r = static_cast<double>(o.reference[i]);
            to_scalar += (r - s[i]) * (r - s[i]);
            to_gabor += (r - g[i]) * (r - g[i]);
            norm += s[i] * s[i];
        }
    }
    EXPECT_LT(std::sqrt(to_scalar / norm), 1e-5);  // the EXR slices are single precision
    EXPECT_GT(std::sqrt(to_gabor / norm), 1e-3);
}
