// The iridescent and brdf design targets against independent evaluations: the loop's gradient
// against finite differences, designs scored from their heights alone (exact_orders, binned
// here), a table made from a relief's own direct-sum far field, hostile spec files, and the
// run directory's x3p.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>

#include "design/evaluator.h"
#include "design/relief.h"
#include "design/target.h"
#include "wavebrdf/design.h"
#include "wavebrdf/design_run.h"
#include "wavebrdf/lobe.h"
#include "wavebrdf/surface_file.h"
#include "wavebrdf/table.h"

namespace wavebrdf {
namespace {

namespace fs = std::filesystem;

fs::path temp_dir(const std::string& name) {
    const fs::path d = fs::temp_directory_path() / ("wavebrdf_design_targets_" + name + "_" + std::to_string(::getpid()));
    fs::remove_all(d);
    fs::create_directories(d);
    return d;
}

std::string write_file(const fs::path& path, const std::string& text) {
    std::ofstream(path, std::ios::binary) << text;
    return path.string();
}

// The loop's loss and gradient against central finite differences (weights as the loop feeds them).
void check_target_gradient(const DesignOptions& options) {
    const PreparedDesign prepared = prepare_design(options);
    detail::Evaluator evaluator(prepared, {0.97, 1.0, 1.03});
    const std::size_t total = static_cast<std::size_t>(options.size * options.size * options.levels);
    std::mt19937_64 rng(11);
    std::uniform_real_distribution<double> uniform(0.1, 1.0);
    std::vector<double> w(total);
    for (double& x : w) x = uniform(rng);
    std::vector<double> g;
    const double loss = evaluator.evaluate(w, &g);
    EXPECT_GT(loss, 0.0);
    const double step = 1e-6;
    for (int trial = 0; trial < 8; ++trial) {
        const std::size_t i = static_cast<std::size_t>(rng() % total);
        std::vector<double> plus = w, minus = w;
        plus[i] += step;
        minus[i] -= step;
        const double fd = (evaluator.evaluate(plus, nullptr) - evaluator.evaluate(minus, nullptr)) / (2 * step);
        EXPECT_NEAR(g[i], fd, 1e-5 * std::max(1.0, std::abs(fd))) << to_string(options.target.kind) << " weight " << i;
    }
}

DesignTarget iridescent(std::vector<IridescentPair> pairs) {
    DesignTarget t;
    t.kind = DesignKind::Iridescent;
    t.text = "iridescent";
    for (auto& p : pairs)
        for (std::size_t c = 0; c < 3; ++c) p.linear_rgb[c] = srgb_decode(p.srgb8[c] / 255.0);
    t.pairs = std::move(pairs);
    return t;
}

DesignTarget brdf(BrdfTable table) {
    DesignTarget t;
    t.kind = DesignKind::Brdf;
    t.text = "brdf";
    t.table = std::make_shared<BrdfTable>(std::move(table));
    return t;
}

// A table of `lights` × `lights` lights within max_sin at `resolution`, each entry the relief's
// own far field: the direct-sum orders (direct_orders: the Kirchhoff integral by the midpoint
// rule, not the FFT identity the design evaluates) binned onto the table's ω_o pixels as power
// per projected solid angle.
BrdfTable table_of_relief(const std::vector<double>& h, int size, double texel_um, double lambda_um, int lights,
                          double max_sin, int resolution) {
    BrdfTable t;
    t.spec.lambdas_um = {lambda_um};
    t.spec.resolution = resolution;
    t.spec.lights = {lights, lights, max_sin};
    light_grid_axes(t.spec.lights, t.light_x, t.light_y, t.rendered);
    const std::size_t n2 = static_cast<std::size_t>(resolution * resolution);
    t.values.assign(static_cast<std::size_t>(lights * lights) * n2 * 3, 0.0f);
    const double area = (2.0 / resolution) * (2.0 / resolution);
    for (int a = 0; a < lights; ++a)
        for (int b = 0; b < lights; ++b) {
            const auto orders = direct_orders(h, size, texel_um, {t.light_x[a], t.light_y[b]}, {lambda_um}, 16)[0];
            for (std::size_t o = 0; o < orders.m.size(); ++o) {
                const int p = static_cast<int>(std::floor((orders.omega_x[o] + 1.0) / 2.0 * resolution));
                const int q = static_cast<int>(std::floor((orders.omega_y[o] + 1.0) / 2.0 * resolution));
                const std::size_t at = ((static_cast<std::size_t>(a * lights + b) * n2) +
                                        static_cast<std::size_t>(p * resolution + q)) * 3;
                for (int c = 0; c < 3; ++c) t.values[at + static_cast<std::size_t>(c)] += static_cast<float>(orders.power[o] / area);
            }
        }
    return t;
}

std::vector<double> random_target_levels(int size, int levels, double step_um, std::uint64_t seed) {
    std::mt19937_64 rng(seed);
    std::vector<double> h(static_cast<std::size_t>(size * size));
    for (double& x : h) x = step_um * static_cast<double>(rng() % static_cast<std::uint64_t>(levels));
    return h;
}

// The brdf target's relative L2 of a relief, from the run's own target and exact evaluation.
double target_l2(const PreparedDesign& p, const std::vector<double>& heights) {
    const auto relief = detail::to_level_relief(heights, detail::k_exact_max_levels);
    const auto flux = detail::level_flux(relief, p.options.size, *p.order_sets, 1.0);
    return p.target->metrics(detail::group_fractions(*p.target, flux))["relative_l2"].get<double>();
}

TEST(DesignTargets, IridescentGradientMatchesFiniteDifferences) {
    DesignOptions o;
    o.size = 8;
    o.levels = 3;
    o.spectral = 6;
    o.band_um = {0.38, 0.78};
    o.omega_i = {0.1, 0.05};
    o.view_cone = 0.15;
    o.target = iridescent({{{-0.1, -0.05}, {32, 192, 64}, {}}, {{0.25, -0.05}, {200, 40, 90}, {}}});
    check_target_gradient(o);
}

TEST(DesignTargets, BrdfGradientMatchesFiniteDifferences) {
    // A lobe over 2 × 2 lights (four light directions, one wavelength) ...
    LobeTableSpec lobe;
    lobe.lobe.alpha_x = 0.3;
    lobe.lobe.alpha_y = 0.15;
    lobe.lights = {2, 2, 0.3};
    lobe.resolution = 12;
    DesignOptions o;
    o.size = 8;
    o.levels = 3;
    o.target = brdf(lobe_table(lobe));
    check_target_gradient(o);
    // ... and a table of three wavelengths mixed to sRGB (values of no particular BRDF).
    BrdfTable t = lobe_table(lobe);
    t.spec.lambdas_um = {0.45, 0.55, 0.65};
    std::mt19937_64 rng(3);
    for (float& v : t.values) v *= static_cast<float>(0.5 + static_cast<double>(rng() % 100) / 100.0);
    o.target = brdf(t);
    check_target_gradient(o);
}

TEST(DesignTargets, BrdfTableOfAReliefsOwnFarFieldIsMatchedByIt) {
    // The binning checked against a table built independently (direct sums, binned above): the
    // relief matches its own table to the direct sum's midpoint-rule error, at four oblique lights;
    // another relief on the same levels does not.
    const int size = 12;
    const std::vector<double> h = random_target_levels(size, 4, 0.11, 5);
    DesignOptions o;
    o.size = size;
    o.levels = 4;
    o.texel_um = 0.5;
    o.target = brdf(table_of_relief(h, size, 0.5, 0.55, 2, 0.4, 24));
    const PreparedDesign p = prepare_design(o);
    EXPECT_EQ(p.order_sets->size(), 4u);  // four lights, one wavelength
    EXPECT_LT(target_l2(p, h), 5e-3);  // 1.7e-3 measured
    EXPECT_GT(target_l2(p, random_target_levels(size, 4, 0.11, 6)), 0.2);
}

TEST(DesignTargets, TwoPairIridescentDesignBeatsItsStart) {
    // Two views, two colours, under white light; scored from the heights alone: exact_orders'
    // power inside each view cone per wavelength (of the incident power), its colour by
    // reflectance_xyz.
    DesignOptions o;
    o.size = 32;
    o.levels = 8;
    o.height_range_um = 2.0;
    o.spectral = 8;
    o.band_um = {0.4, 0.7};
    o.view_cone = 0.08;
    o.iterations = 60;
    o.refine_passes = 20;
    // The schedule alone: the brightness trade gives up Δu′v′ (up to the ceiling) for a dim pair's
    // Y, and has its own test (design_brightness_test.cpp).
    o.delta_uv_ceiling = 0.0;
    o.target = iridescent({{{0.2, 0.0}, {255, 128, 0}, {}}, {{-0.2, 0.0}, {0, 128, 255}, {}}});
    const PreparedDesign p = prepare_design(o);
    auto score = [&](const std::vector<double>& heights) {
        const auto orders = exact_orders(heights, o.size, o.texel_um, o.omega_i, p.lambdas_um);
        std::vector<double> delta;
        for (const auto& pair : o.target.pairs) {
            std::vector<double> reflectance;
            for (const auto& w : orders) {
                double r = 0.0;
                for (std::size_t k = 0; k < w.m.size(); ++k)
                    if (std::hypot(w.omega_x[k] - pair.view[0], w.omega_y[k] - pair.view[1]) <= o.view_cone) r += w.power[k] * w.kirchhoff_total;
                reflectance.push_back(r);
            }
            const auto uv = xyz_to_uv(reflectance_xyz(p.lambdas_um, reflectance));
            const auto target = xyz_to_uv(linear_srgb_to_xyz(pair.linear_rgb));
            delta.push_back(std::hypot(uv[0] - target[0], uv[1] - target[1]));
        }
        return delta;
    };
    const DesignResult r = run_design(p);
    DesignOptions start = o;
    start.iterations = 0;
    start.refine_passes = 0;
    const auto designed = score(r.heights_um);
    const auto random = score(run_design(prepare_design(start)).heights_um);
    for (std::size_t k = 0; k < designed.size(); ++k) {
        EXPECT_LT(designed[k], 0.02) << "pair " << k;
        EXPECT_LT(designed[k], random[k] / 3) << "pair " << k;
    }
    // design.json's exact metrics are the same numbers.
    const auto j = nlohmann::json::parse(r.metrics_json);
    for (std::size_t k = 0; k < designed.size(); ++k)
        EXPECT_NEAR(j["metrics"]["exact"]["delta_uv"][k].get<double>(), designed[k], 1e-9);
}

TEST(DesignTargets, BrdfDesignAgainstALobeImprovesItsRelativeL2) {
    // A GGX lobe (wavebrdf lobe's table, normal light); the design's relative L2 computed here from
    // exact_orders of its heights binned onto the table's pixels, against its random start.
    LobeTableSpec lobe;
    lobe.lobe.alpha_x = lobe.lobe.alpha_y = 0.15;
    lobe.lights = {1, 1, 0.9};
    lobe.resolution = 32;
    const BrdfTable table = lobe_table(lobe);
    DesignOptions o;
    o.size = 48;
    o.levels = 8;
    o.height_range_um = 1.0;
    o.iterations = 60;
    o.refine_passes = 20;
    o.target = brdf(table);
    auto l2 = [&](const std::vector<double>& heights) {
        const auto w = exact_orders(heights, o.size, o.texel_um, {0.0, 0.0}, {0.5})[0];
        const int n = 32;
        std::vector<double> f(static_cast<std::size_t>(n * n), 0.0);
        for (std::size_t k = 0; k < w.m.size(); ++k) {
            const int p = static_cast<int>(std::floor((w.omega_x[k] + 1.0) / 2.0 * n));
            const int q = static_cast<int>(std::floor((w.omega_y[k] + 1.0) / 2.0 * n));
            f[static_cast<std::size_t>(p * n + q)] += w.power[k] / ((2.0 / n) * (2.0 / n));
        }
        double d2 = 0.0, t2 = 0.0;
        for (std::size_t q = 0; q < f.size(); ++q) {
            const double t = double(table.values[q * 3]);
            d2 += (f[q] - t) * (f[q] - t);
            t2 += t * t;
        }
        return std::sqrt(d2 / t2);
    };
    const DesignResult r = run_design(prepare_design(o));
    DesignOptions start = o;
    start.iterations = 0;
    start.refine_passes = 0;
    const double designed = l2(r.heights_um), random = l2(run_design(prepare_design(start)).heights_um);
    EXPECT_LT(designed, 0.25);
    EXPECT_LT(designed, random / 3);
    const auto j = nlohmann::json::parse(r.metrics_json);
    EXPECT_NEAR(j["metrics"]["exact"]["relative_l2"].get<double>(), designed, 1e-9);
}

TEST(DesignTargets, HostileSpecsAndTablesGetOneLine) {
    const fs::path d = temp_dir("hostile");
    auto fails = [&](const std::string& text, const std::string& part) {
        try {
            parse_design_target(text);
            ADD_FAILURE() << text << " was accepted";
        } catch (const std::invalid_argument& e) {
            const std::string what = e.what();
            EXPECT_NE(what.find(part), std::string::npos) << what;
            EXPECT_EQ(what.find('\n'), std::string::npos) << what;
        }
    };
    auto spec = [&](const std::string& name, const std::string& json) {
        return "iridescent:" + write_file(d / name, json);
    };
    const std::string good = R"({"pairs": [{"view": [0.2, 0.1], "colour": "#ff8000"}, {"view": [-0.2, 0], "color": "#0080FF"}]})";
    const DesignTarget t = parse_design_target(spec("good.json", good));
    ASSERT_EQ(t.pairs.size(), 2u);
    EXPECT_EQ(t.pairs[0].srgb8, (std::array<int, 3>{255, 128, 0}));
    EXPECT_DOUBLE_EQ(t.pairs[1].view[0], -0.2);
    fails("iridescent:", "names no file");
    fails("iridescent:" + (d / "absent.json").string(), "absent.json");
    fails(spec("notjson.json", "{pairs: 1"), "not valid JSON");
    fails(spec("deep.json", std::string(100000, '[')), "more than");
    fails(spec("nested.json", "{\"pairs\": [[[[[[1]]]]]]}"), "nested deeper");
    fails(spec("nopairs.json", "{\"pair\": []}"), "no array 'pairs'");
    fails(spec("extra.json", "{\"pairs\": [{\"view\": [0, 0], \"colour\": \"#ffffff\"}], \"x\": 1}"), "unknown field 'x'");
    fails(spec("empty.json", "{\"pairs\": []}"), "0 pairs");
    std::string many = "{\"pairs\": [";
    for (int k = 0; k < 17; ++k) many += std::string(k ? "," : "") + "{\"view\": [0, 0], \"colour\": \"#ffffff\"}";
    fails(spec("many.json", many + "]}"), "17 pairs");
    fails(spec("outside.json", "{\"pairs\": [{\"view\": [0.9, 0.5], \"colour\": \"#ffffff\"}]}"), "visible disk");
    fails(spec("nan.json", "{\"pairs\": [{\"view\": [\"a\", 0], \"colour\": \"#ffffff\"}]}"), "'view'");
    fails(spec("colour.json", "{\"pairs\": [{\"view\": [0, 0], \"colour\": \"red\"}]}"), "#RRGGBB");
    fails(spec("black.json", "{\"pairs\": [{\"view\": [0, 0], \"colour\": \"#000000\"}]}"), "black");
    // Cones that overlap, or reach outside the disk, are refused when the cone is known.
    DesignOptions o;
    o.size = 8;
    o.spectral = 4;
    o.target = parse_design_target(spec("close.json", R"({"pairs": [{"view": [0.1, 0], "colour": "#ff0000"},
        {"view": [0.15, 0], "colour": "#00ff00"}]})"));
    EXPECT_THROW(prepare_design(o), std::invalid_argument);
    o.target = parse_design_target(spec("good.json", good));
    o.spectral = 0;  // needs white light
    EXPECT_THROW(prepare_design(o), std::invalid_argument);
    // A 4² tile of 0.5 µm texels has orders λ/2 µm ≥ 0.2 apart: a cone of 0.02 about (0.1, 0.1)
    // holds none at any wavelength.
    o.size = 4;
    o.spectral = 4;
    o.band_um = {0.4, 0.7};
    o.view_cone = 0.02;
    o.target = parse_design_target(spec("between.json", R"({"pairs": [{"view": [0.1, 0.1], "colour": "#ff0000"}]})"));
    try {
        prepare_design(o);
        ADD_FAILURE() << "a cone between the orders was accepted";
    } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("holds no diffraction order"), std::string::npos) << e.what();
    }
    // Tables: not a table, and a mosaic whose header declares more pixels than a design reads
    // (refused before its pixels are read: the file holds only a header).
    fails("brdf:" + (d / "absent.exr").string(), "absent.exr");
    fails("brdf:" + write_file(d / "text.exr", "not an exr"), "no OpenEXR data window");
    std::string header("\x76\x2f\x31\x01\x02\x00\x00\x00", 8);
    header += std::string("dataWindow\0box2i\0", 17) + std::string("\x10\x00\x00\x00", 4);
    header += std::string("\x00\x00\x00\x00\x00\x00\x00\x00\x0f\x27\x00\x00\x0f\x27\x00\x00", 16);
    header += std::string(1, '\0');
    fails("brdf:" + write_file(d / "huge.exr", header), "10000 x 10000");
    LobeTableSpec lobe;
    lobe.lights = {1, 1, 0.5};
    lobe.resolution = 8;
    write_brdf_table((d / "lobe.exr").string(), lobe_table(lobe));
    o = DesignOptions{};
    o.target = parse_design_target("brdf:" + (d / "lobe.exr").string());
    EXPECT_EQ(o.target.table->spec.resolution, 8);
    o.spectral = 8;  // the wavelengths are the table's
    EXPECT_THROW(prepare_design(o), std::invalid_argument);
    fs::remove_all(d);
}

TEST(DesignTargets, RunDirectoryHoldsAnX3pWithTheSameHeights) {
    // heights.x3p read back by the surface reader (the x3p plugin), as the model's heightfield:
    // the design's heights in µm, transposed back (from_heightfield / to_heightfield).
    DesignOptions o;
    o.size = 16;
    o.spectral = 3;
    o.band_um = {0.45, 0.65};
    o.levels = 4;
    o.height_range_um = 1.0;
    o.iterations = 4;
    o.refine_passes = 2;
    const DesignResult r = run_design(prepare_design(o));
    const fs::path d = temp_dir("x3p");
    fs::remove_all(d);
    write_design_directory(d.string(), r, false);
    const auto j = nlohmann::json::parse(std::ifstream(d / "design.json"));
    ASSERT_EQ(j["fabrication_files"]["heights_x3p"], "heights.x3p") << j["fabrication_files"].dump();
    const MeasuredSurface s = read_surface((d / "heights.x3p").string());
    EXPECT_EQ(s.format, "x3p");
    const Heightfield hf = to_heightfield(s, "heights.x3p");
    ASSERT_EQ(hf.rows(), 16);
    ASSERT_EQ(hf.cols(), 16);
    for (int i = 0; i < 16; ++i)
        for (int k = 0; k < 16; ++k)
            EXPECT_NEAR(hf.height_um(i, k), r.heights_um[static_cast<std::size_t>(i * 16 + k)], 1e-12);
    fs::remove_all(d);
}

}  // namespace
}  // namespace wavebrdf
