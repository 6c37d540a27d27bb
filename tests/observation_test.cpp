// The multi-observation loss and its gradient: finite differences over spectral and
// single-wavelength observations at several positions and light directions, and the JSON
// round trip.
#include <gtest/gtest.h>

#include <cmath>

#include <filesystem>
#include <fstream>

#include "test_util.h"
#include "wavebrdf/memory.h"
#include "wavebrdf/observation.h"
#include "wavebrdf/spectrum.h"

using namespace wavebrdf;
using wavebrdf::test::random_heightfield;

namespace {

Observation make_observation(const Heightfield& truth, double x, double y, std::array<double, 2> light,
                             std::vector<double> lambdas, Model model = Model::OHS) {
    Observation o;
    o.query.x_um = x;
    o.query.y_um = y;
    o.query.sigma_p_um = 2.5;
    o.query.omega_i = light;
    o.query.model = model;
    o.lambdas_um = std::move(lambdas);
    o.resolution = 16;
    o.reference = to_reference(render_observation(truth, o));
    return o;
}

RenderOptions exact() {
    RenderOptions o;
    o.prune_tolerance = 0.0;
    return o;
}

}  // namespace

TEST(ObservationTest, LossIsZeroAtTheTruth) {
    const Heightfield truth = random_heightfield(12, 12, 0.3, 4, 1.0, 1.0);
    const std::vector<Observation> obs = {make_observation(truth, 6, 6, {0, 0}, {0.5}),
                                          make_observation(truth, 2, 9, {0.2, 0}, spectral_wavelengths_um(4))};
    for (const char* name : {"cmsle:1", "mse", "amplitude"}) {
        std::vector<double> grad;
        // 0 up to the references' rounding to float (2^-24 relative per value).
        EXPECT_NEAR(observation_loss(truth, obs, parse_loss(name), &grad, exact()), 0.0, 1e-13) << name;
        EXPECT_LT(test::max_abs(grad), 1e-8) << name;
    }
}

TEST(ObservationTest, GradientMatchesFiniteDifferences) {
    const Heightfield truth = random_heightfield(12, 10, 0.3, 5, 1.0, 1.0);
    const Heightfield guess = random_heightfield(12, 10, 0.3, 6, 1.0, 1.0);
    const std::vector<Observation> obs = {make_observation(truth, 6, 5, {0.0, 0.0}, {0.5}),
                                          make_observation(truth, 1, 8, {0.2, -0.1}, spectral_wavelengths_um(3)),
                                          make_observation(truth, 9, 2, {-0.1, 0.3}, {0.6}, Model::GHS)};
    for (const char* name : {"cmsle:1", "cmsle:0.01", "mse", "amplitude"}) {
        const Loss loss = parse_loss(name);
        std::vector<double> grad;
        observation_loss(guess, obs, loss, &grad, exact());
        double scale = test::max_abs(grad);
        ASSERT_GT(scale, 0.0) << name;
        // Central differences with one Richardson step: the amplitude loss's √ has large
        // higher derivatives where a pixel is nearly dark.
        auto central = [&](std::size_t cell, double h) {
            std::vector<double> plus = guess.values(), minus = guess.values();
            plus[cell] += h;
            minus[cell] -= h;
            return (observation_loss(guess.with_values(plus), obs, loss, nullptr, exact()) -
                    observation_loss(guess.with_values(minus), obs, loss, nullptr, exact())) /
                   (2 * h);
        };
        for (std::size_t cell = 0; cell < grad.size(); cell += 13) {
            const double fd = (4 * central(cell, 5e-6) - central(cell, 1e-5)) / 3;
            EXPECT_LE(std::abs(fd - grad[cell]), 1e-6 * scale) << name << " cell " << cell;
        }
    }
}

TEST(ObservationTest, JsonRoundTripAndErrors) {
    const Heightfield truth = random_heightfield(8, 8, 0.3, 7, 1.0, 1.0);
    const std::vector<Observation> obs = {
        make_observation(truth, 3, 4, {0.1, 0.2}, spectral_wavelengths_um(3), Model::ROHS)};
    const std::filesystem::path dir = std::filesystem::path(WAVEBRDF_TEST_TMP) / "observation_test";
    std::filesystem::create_directories(dir);
    const std::string path = (dir / "obs.json").string();
    write_observations_json(path, obs);
    const auto back = read_observations_json(path);
    ASSERT_EQ(back.size(), 1u);
    EXPECT_EQ(back[0].reference, obs[0].reference);
    EXPECT_EQ(back[0].lambdas_um, obs[0].lambdas_um);
    EXPECT_EQ(back[0].query.model, Model::ROHS);
    EXPECT_EQ(back[0].query.omega_i, obs[0].query.omega_i);

    auto write = [&](const std::string& text) {
        std::ofstream(path) << text;
        return path;
    };
    auto expect_error = [&](const std::string& text, const std::string& needle) {
        try {
            read_observations_json(write(text));
            ADD_FAILURE() << "no error for " << text;
        } catch (const std::runtime_error& e) {
            EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
        }
    };
    expect_error("{", "not valid JSON");
    expect_error(R"({"observations": []})", "empty");
    expect_error(
        R"({"observations": [{"y_um": 0, "sigma_p_um": 2, "lambda_um": 0.5, "resolution": 1, "reference": [1]}]})",
        "'x_um'");
    expect_error(
        R"({"observations": [{"x_um": 0, "y_um": 0, "sigma_p_um": 2, "lambda_um": 0.5, "resolution": 2, "reference": [1, 2]}]})",
        "reference has 2 values");
    expect_error(
        R"({"observations": [{"x_um": 0, "y_um": 0, "sigma_p_um": 2, "lambda_um": 0.5, "spectral": 3, "resolution": 1, "reference": [1]}]})",
        "exactly one");
    expect_error(
        R"({"observations": [{"x_um": 0, "y_um": 0, "sigma_p_um": -2, "lambda_um": 0.5, "resolution": 1, "reference": [1]}]})",
        "sigma_p");
    expect_error(
        R"({"observations": [{"x_um": "a", "y_um": 0, "sigma_p_um": 2, "lambda_um": 0.5, "resolution": 1, "reference": [1]}]})",
        "wrong type");
}

// Issue 9: integer fields were read with get<int>(): "resolution": 8.7 became 8 and 2^40 + 8
// wrapped to 8; "spectral" had no upper bound (the CLI caps 256). Each is refused, naming the
// file, the field and the range; an integral 1.0 (tools that only write doubles) is accepted.
// write_observations_json writes what read_observations_json reads: every field, one and
// several wavelengths, references inline (exact) or as EXR files in a folder beside the JSON
// (float precision: values that are floats come back exactly). The EXR form is the one
// `wavebrdf recover --save-observations` writes (it used to be written by the CLI itself).
TEST(ObservationTest, WrittenObservationsReadBackTheSame) {
    const Heightfield truth = random_heightfield(8, 8, 0.3, 11, 1.0, 1.0);
    std::vector<Observation> obs = {
        make_observation(truth, 3, 4, {0.1, 0.2}, {0.55}, Model::OHS),
        make_observation(truth, -1.5, 2.25, {0.0, -0.3}, spectral_wavelengths_um(3), Model::ROHS)};
    obs[1].resolution = 8;
    obs[1].reference = to_reference(render_observation(truth, obs[1]));
    const std::filesystem::path dir = std::filesystem::path(WAVEBRDF_TEST_TMP) / "observation_test" / "round_trip";
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    for (const ReferenceStorage storage : {ReferenceStorage::Inline, ReferenceStorage::Exr}) {
        const bool exr = storage == ReferenceStorage::Exr;
        SCOPED_TRACE(exr ? "exr" : "inline");
        const std::string path = (dir / (exr ? "saved.json" : "inline.json")).string();
        write_observations_json(path, obs, storage);
        EXPECT_EQ(std::filesystem::exists(dir / "saved" / "slice_0001.exr"), exr);
        const std::vector<Observation> back = read_observations_json(path);
        ASSERT_EQ(back.size(), obs.size());
        for (std::size_t i = 0; i < obs.size(); ++i) {
            EXPECT_EQ(back[i].query.x_um, obs[i].query.x_um);
            EXPECT_EQ(back[i].query.y_um, obs[i].query.y_um);
            EXPECT_EQ(back[i].query.sigma_p_um, obs[i].query.sigma_p_um);
            EXPECT_EQ(back[i].query.omega_i, obs[i].query.omega_i);
            EXPECT_EQ(back[i].query.model, obs[i].query.model);
            EXPECT_EQ(back[i].lambdas_um, obs[i].lambdas_um);
            EXPECT_EQ(back[i].resolution, obs[i].resolution);
            EXPECT_EQ(back[i].reference, obs[i].reference);
        }
    }
    // Inline references keep every float (the reference is float; the JSON number is its exact
    // double, read back to the same float).
    obs[0].reference[0] = 0.1f;
    obs[0].reference[1] = std::nextafter(0.3f, 1.0f);
    write_observations_json((dir / "exact.json").string(), obs);
    const std::vector<Observation> exact = read_observations_json((dir / "exact.json").string());
    EXPECT_EQ(exact[0].reference[0], 0.1f);
    EXPECT_EQ(exact[0].reference[1], std::nextafter(0.3f, 1.0f));
    // No file name to name the folder after.
    EXPECT_THROW(write_observations_json((dir / "..").string(), obs, ReferenceStorage::Exr), std::invalid_argument);
}

TEST(ObservationTest, JsonIntegerFieldsMustBeIntegersInRange) {
    const std::filesystem::path dir = std::filesystem::path(WAVEBRDF_TEST_TMP) / "observation_test";
    std::filesystem::create_directories(dir);
    const std::string path = (dir / "ints.json").string();
    const auto json_with = [&](const std::string& fields) {
        std::ofstream(path) << R"({"observations": [{"x_um": 0, "y_um": 0, "sigma_p_um": 2, )" << fields
                            << R"(, "reference": [1]}]})";
    };
    const auto expect_error = [&](const std::string& fields, const std::string& needle) {
        json_with(fields);
        try {
            read_observations_json(path);
            ADD_FAILURE() << "no error for " << fields;
        } catch (const std::runtime_error& e) {
            const std::string message = e.what();
            EXPECT_NE(message.find(path), std::string::npos) << message;
            EXPECT_NE(message.find(needle), std::string::npos) << message;
        }
    };
    expect_error(R"("lambda_um": 0.5, "resolution": 8.7)",
                 "field 'resolution' is 8.7; expected an integer from 1 to 8192");
    expect_error(R"("lambda_um": 0.5, "resolution": 1099511627784)",
                 "field 'resolution' is 1099511627784; expected an integer from 1 to 8192");
    expect_error(R"("lambda_um": 0.5, "resolution": -1)", "from 1 to 8192");
    expect_error(R"("lambda_um": 0.5, "resolution": "1")", "field 'resolution'");
    expect_error(R"("spectral": 100000, "resolution": 1)",
                 "field 'spectral' is 100000; expected an integer from 1 to 256");
    expect_error(R"("spectral": 2.5, "resolution": 1)", "field 'spectral' is 2.5");
    expect_error(R"("spectral": 4294967299, "resolution": 1)", "field 'spectral' is 4294967299");
    json_with(R"("lambda_um": 0.5, "resolution": 1.0)");
    EXPECT_EQ(read_observations_json(path).at(0).resolution, 1);
}

// Issue 9: an observation set is estimated from its JSON before any reference image is read;
// 2000 references of 8192² RGB (3.2 TB) used to be read one by one until memory ran out.
TEST(ObservationTest, ObservationSetThatCannotFitIsRefusedBeforeReadingReferences) {
    const std::filesystem::path dir = std::filesystem::path(WAVEBRDF_TEST_TMP) / "observation_test";
    std::filesystem::create_directories(dir);
    const std::string path = (dir / "huge_set.json").string();
    {
        std::ofstream out(path);
        out << R"({"observations": [)";
        for (int i = 0; i < 2000; ++i)
            out << (i ? "," : "")
                << R"({"x_um": 0, "y_um": 0, "sigma_p_um": 2, "spectral": 8, "resolution": 8192, "reference": "missing.exr"})";
        out << "]}";
    }
    try {
        read_observations_json(path, 1.0);
        ADD_FAILURE() << "no error";
    } catch (const OutOfMemory& e) {
        const std::string message = e.what();
        EXPECT_NE(message.find("reading the 2000 observations of " + path + " needs about"), std::string::npos)
            << message;
        EXPECT_NE(message.find("(max-memory-gb)"), std::string::npos) << message;
    }
}

// The plan cache gives the uncached loss and gradient bit for bit, builds each observation's
// plan once however many epochs use it, and the gradient accumulates (adjoint.h).
TEST(ObservationPlansTest, CachedLossEqualsUncachedAndBuildsEachPlanOnce) {
    const Heightfield truth = random_heightfield(16, 16, 0.3, 21, 1.0, 1.0);
    std::vector<Observation> obs(2);
    obs[0].query = test::make_query(Model::OHS, 5.0, 6.0, 3.0, 0.1, 0.0);
    obs[0].lambdas_um = spectral_wavelengths_um(3);
    obs[0].resolution = 12;
    obs[1].query = test::make_query(Model::OHS, 11.0, 2.0, 3.0);
    obs[1].lambdas_um = {0.5};
    obs[1].resolution = 10;
    for (Observation& o : obs) o.reference = to_reference(render_observation(truth, o));
    const Loss loss{LossKind::CMSLE, 1.0};
    ObservationPlans plans;
    for (std::uint64_t seed : {22u, 23u, 24u}) {
        const Heightfield estimate = random_heightfield(16, 16, 0.3, seed, 1.0, 1.0);
        std::vector<double> g_plain, g_cached;
        const double plain = observation_loss(estimate, obs, loss, &g_plain);
        const double cached = observation_loss(estimate, obs, loss, &g_cached, {}, nullptr, &plans);
        EXPECT_EQ(plain, cached);
        EXPECT_EQ(g_plain, g_cached);
        // A non-empty gradient is added to.
        std::vector<double> twice = g_plain;
        observation_loss(estimate, obs, loss, &twice, {}, nullptr, &plans);
        for (std::size_t i = 0; i < twice.size(); ++i)
            EXPECT_NEAR(twice[i], 2.0 * g_plain[i], 1e-12 * test::max_abs(g_plain));
    }
    EXPECT_EQ(plans.built(), 2u);
    EXPECT_EQ(plans.size(), 2u);
    std::vector<double> wrong(3);
    test::expect_throw_naming<std::invalid_argument>([&] { observation_loss(truth, obs, loss, &wrong); },
                                                     "gradient has 3 entries");
}
