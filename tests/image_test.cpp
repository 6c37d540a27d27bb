// Camera images against independent evaluations: pixels against render_slice of their own
// footprint at their own direction (geometry computed here by hand), a flat mirror's one
// highlight at the hand-computed mirror point, a grating's orders where the grating equation
// puts them, reciprocity under swapping light and camera, the pruning bound, bad input.
#include "wavebrdf/image.h"

#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "image_util.h"
#include "test_util.h"
#include "wavebrdf/brdf.h"
#include "wavebrdf/gabor.h"
#include "wavebrdf/point_eval.h"
#include "wavebrdf/spectrum.h"

namespace wavebrdf {
namespace {

using test::brightest;
using test::cross3;
using test::unit;
using test::value_at;
using test::Vec3;

// A pinhole camera at `camera` looking at the origin, up +z, over a square plate.
ImageOptions looking_at_origin(const Vec3& camera, double fov_deg, int rows, int cols, double plate_um) {
    ImageOptions o;
    o.camera.position = camera;
    o.camera.look_at = {0.0, 0.0, 0.0};
    o.camera.up = {0.0, 0.0, 1.0};
    o.camera.fov_deg = fov_deg;
    o.camera.rows = rows;
    o.camera.cols = cols;
    o.plane_size_um = {plate_um, plate_um};
    return o;
}

// An orthographic camera along −ω_o (ω_o a slice pixel centre) and a directional light: every
// pixel's value is the slice pixel of its own footprint, times cos θ_i.
TEST(Image, PixelsEqualRenderSliceOfTheirOwnFootprint) {
    const Heightfield hf = test::random_heightfield(48, 40, 0.3, 17, 1.0, 1.0);
    const int n = 21, p = 7, q = 12;  // the slice pixel whose direction the camera looks from
    const double ox = slice_omega(p, n), oy = slice_omega(q, n);
    const Vec3 wo{ox, oy, std::sqrt(1.0 - ox * ox - oy * oy)};
    const std::array<double, 2> wi{{0.25, -0.1}};
    const Vec3 light{wi[0], wi[1], std::sqrt(1.0 - wi[0] * wi[0] - wi[1] * wi[1])};
    for (Model model : {Model::OHS, Model::GHS, Model::ROHS, Model::RGHS, Model::Kirchhoff}) {
        ImageOptions o;
        o.camera.orthographic = true;
        o.camera.position = {300.0 * wo[0] + 3.0, 300.0 * wo[1] - 2.0, 300.0 * wo[2]};
        o.camera.look_at = {3.0, -2.0, 0.0};
        o.camera.up = {0.0, 0.0, 1.0};
        o.camera.view_width_um = 60.0;
        o.camera.rows = 9;
        o.camera.cols = 11;
        o.plane_size_um = {400.0, 400.0};
        o.lights = {ImageLight{LightKind::Directional, light}};
        o.lambdas_um = {0.55};
        o.model = model;
        o.sigma_p_um = 4.0;
        o.prune_tolerance = 0.0;
        const RgbImage image = render_image(hf, prepare_image(hf, o));
        // The camera's frame and each pixel's hit point, by hand.
        const Vec3 f = unit({-wo[0], -wo[1], -wo[2]});
        const Vec3 up{0.0, 0.0, 1.0};
        Vec3 right = unit(cross3(f, up));
        const Vec3 u2{right[1] * f[2] - right[2] * f[1], right[2] * f[0] - right[0] * f[2],
                      right[0] * f[1] - right[1] * f[0]};
        std::mt19937_64 rng(3);
        for (int trial = 0; trial < 8; ++trial) {
            const int r = static_cast<int>(rng() % 9), c = static_cast<int>(rng() % 11);
            const double sx = ((c + 0.5) / 11 * 2 - 1) * 30.0 * 11.0 / 9.0, sy = (1 - (r + 0.5) / 9 * 2) * 30.0;
            Vec3 origin;
            for (int k = 0; k < 3; ++k) origin[k] = o.camera.position[k] + sx * right[k] + sy * u2[k];
            const double t = -origin[2] / f[2];
            const double px = origin[0] + t * f[0], py = origin[1] + t * f[1];
            Query query;
            query.model = model;
            query.x_um = px + 200.0;  // texel (0, 0) at the plate's corner (−200, −200)
            query.y_um = py + 200.0;
            query.sigma_p_um = 4.0;
            query.omega_i = wi;
            RenderOptions direct;
            direct.path = RenderPath::Direct;
            direct.prune_tolerance = 0.0;
            const std::vector<double> slice = render_slice<double>(hf, query, 0.55, n, direct);
            const double expected = slice[std::size_t(p) * n + q] * light[2];
            EXPECT_NEAR(value_at(image, r, c), expected, 1e-6 * expected)
                << to_string(model) << " pixel " << r << "," << c;
            EXPECT_EQ(value_at(image, r, c, 0), value_at(image, r, c, 2));  // one wavelength: grey
        }
    }
}

// Two lights give the sum of their images; a pixel whose ray misses the plate (by hand: a camera
// looking straight down) holds the background, every other pixel a lit value.
TEST(Image, LightsAddAndMissedPixelsHoldTheBackground) {
    const Heightfield hf = test::random_heightfield(32, 32, 0.3, 9, 1.0, 1.0);
    const double height = 400.0, plate = 200.0, half = std::tan(20.0 * k_pi / 180.0);
    ImageOptions o;
    o.camera.position = {0.0, 0.0, height};
    o.camera.look_at = {0.0, 0.0, 0.0};  // straight down: up is −x, columns run along +y
    o.camera.fov_deg = 40.0;
    o.camera.rows = 12;
    o.camera.cols = 10;
    o.plane_size_um = {plate, plate};
    o.lambdas_um = {0.45, 0.55, 0.65};
    o.sigma_p_um = 3.0;
    o.prune_tolerance = 0.0;
    const ImageLight point{LightKind::Point, {150.0, -60.0, 500.0}};
    const ImageLight directional{LightKind::Directional, {-0.3, 0.4, 1.0}};
    auto values = [&](std::vector<ImageLight> lights, std::array<double, 3> background) {
        ImageOptions with = o;
        with.lights = std::move(lights);
        with.background = background;
        return render_image_values(hf, prepare_image(hf, with));
    };
    const std::vector<double> a = values({point}, {0.0, 0.0, 0.0}), b = values({directional}, {0.0, 0.0, 0.0});
    const std::vector<double> both = values({point, directional}, {0.0, 0.0, 0.0});
    const double peak = test::max_abs(both);
    ASSERT_GT(peak, 0.0);
    for (std::size_t k = 0; k < both.size(); ++k) EXPECT_NEAR(both[k], a[k] + b[k], 1e-12 * peak) << "value " << k;
    const std::array<double, 3> background{0.25, 0.5, 0.75};
    const std::vector<double> shown = values({point, directional}, background);
    int hits = 0, misses = 0;
    for (int r = 0; r < o.camera.rows; ++r)
        for (int c = 0; c < o.camera.cols; ++c) {
            const double sy = (1.0 - (r + 0.5) / o.camera.rows * 2.0) * half;
            const double sx = ((c + 0.5) / o.camera.cols * 2.0 - 1.0) * half * o.camera.cols / o.camera.rows;
            const double x = -sy * height, y = sx * height;
            const bool hit = std::abs(x) < 0.5 * plate && std::abs(y) < 0.5 * plate;
            for (std::size_t ch = 0; ch < 3; ++ch) {
                const std::size_t k = (std::size_t(r) * o.camera.cols + c) * 3 + ch;
                const double expected = hit ? both[k] : background[ch];
                EXPECT_EQ(shown[k], expected)
                    << "pixel " << r << "," << c << (hit ? " sees" : " misses") << " the plate";
            }
            // Lit: its luminance is positive (a channel of a few wavelengths' mix may be negative).
            const double* rgb = &both[(std::size_t(r) * o.camera.cols + c) * 3];
            const double luminance = 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2];
            EXPECT_TRUE(!hit || luminance > 0.0) << "pixel " << r << "," << c << " luminance " << luminance;
            hits += hit;
            misses += !hit;
        }
    EXPECT_GT(hits, 20);
    EXPECT_GT(misses, 20);
}

// A direction is a direction whatever its length: a directional light or an up vector with
// huge or tiny components gives the image of the same direction at unit scale, bit for bit.
TEST(Image, DirectionsOfAnyLengthGiveTheSameImage) {
    const Heightfield hf = test::random_heightfield(16, 16, 0.3, 21, 1.0, 1.0);
    ImageOptions o = looking_at_origin({-100.0, 30.0, 300.0}, 30.0, 5, 5, 200.0);
    o.lambdas_um = {0.5};
    o.sigma_p_um = 3.0;
    o.lights = {ImageLight{LightKind::Directional, {0.5, -0.25, 1.0}}};
    const std::vector<double> unit_scale = render_image_values(hf, prepare_image(hf, o));
    ASSERT_GT(test::max_abs(unit_scale), 0.0);
    for (double scale : {1e300, 1e-300}) {
        ImageOptions scaled = o;
        scaled.lights[0].vector = {0.5 * scale, -0.25 * scale, scale};
        scaled.camera.up = {0.0, 0.0, scale};
        EXPECT_EQ(render_image_values(hf, prepare_image(hf, scaled)), unit_scale) << "scale " << scale;
    }
}

// A blackbody light weighs each wavelength by Planck's law normalised to mean 1 over the
// samples: the image's per-wavelength parts, recovered from the white image through the 3 x 3
// spectral mix, weighted by B(λ, T) computed here from h, c and k.
TEST(Image, BlackbodyLightWeighsEachWavelengthByPlanck) {
    const Heightfield hf = test::random_heightfield(32, 32, 0.3, 13, 1.0, 1.0);
    ImageOptions o = looking_at_origin({-150.0, 40.0, 400.0}, 30.0, 6, 6, 300.0);
    o.lambdas_um = {0.45, 0.55, 0.65};
    o.sigma_p_um = 3.0;
    o.prune_tolerance = 0.0;
    ImageLight light{LightKind::Point, {200.0, -50.0, 450.0}};
    o.lights = {light};
    const std::vector<double> white = render_image_values(hf, prepare_image(hf, o));
    const double temperature = 2700.0;
    o.lights[0].spectrum = LightSpectrum::Blackbody;
    o.lights[0].temperature_k = temperature;
    const std::vector<double> warm = render_image_values(hf, prepare_image(hf, o));
    const double h = 6.62607015e-34, c = 2.99792458e8, k = 1.380649e-23;
    std::array<double, 3> planck{};
    double mean = 0.0;
    for (std::size_t l = 0; l < 3; ++l) {
        const double lambda_m = o.lambdas_um[l] * 1e-6;
        planck[l] = 2.0 * h * c * c / std::pow(lambda_m, 5.0) / (std::exp(h * c / (lambda_m * k * temperature)) - 1.0);
        mean += planck[l] / 3.0;
    }
    const std::vector<double> m = spectral_mix_weights(o.lambdas_um);  // M[ch * 3 + l]
    const double det = m[0] * (m[4] * m[8] - m[5] * m[7]) - m[1] * (m[3] * m[8] - m[5] * m[6]) +
                       m[2] * (m[3] * m[7] - m[4] * m[6]);
    ASSERT_GT(std::abs(det), 1e-6);
    const double peak = test::max_abs(warm);
    ASSERT_GT(peak, 0.0);
    for (std::size_t p = 0; p < white.size() / 3; ++p) {
        // f = M⁻¹ rgb by Cramer's rule, then M diag(B/mean) f.
        const double* w = &white[3 * p];
        std::array<double, 3> f{};
        for (std::size_t l = 0; l < 3; ++l) {
            std::array<double, 9> a = {m[0], m[1], m[2], m[3], m[4], m[5], m[6], m[7], m[8]};
            for (std::size_t ch = 0; ch < 3; ++ch) a[ch * 3 + l] = w[ch];
            f[l] = (a[0] * (a[4] * a[8] - a[5] * a[7]) - a[1] * (a[3] * a[8] - a[5] * a[6]) +
                    a[2] * (a[3] * a[7] - a[4] * a[6])) /
                   det;
        }
        for (std::size_t ch = 0; ch < 3; ++ch) {
            double expected = 0.0;
            for (std::size_t l = 0; l < 3; ++l) expected += m[ch * 3 + l] * planck[l] / mean * f[l];
            EXPECT_NEAR(warm[3 * p + ch], expected, 1e-9 * peak) << "pixel " << p << " channel " << ch;
        }
    }
    // And the weights themselves are a warm light's: B(0.65 µm) / B(0.45 µm) ≈ 6 at 2700 K.
    EXPECT_GT(planck[2] / planck[0], 3.0);
}

// A flat mirror under a point light: one highlight, at the pixel that sees the mirror image of
// the light.
TEST(Image, FlatMirrorShowsOneHighlightAtTheMirrorPoint) {
    const Heightfield flat(16, 16, std::vector<double>(256, 0.0), 1.0, 1.0);
    ImageOptions o;
    const Vec3 cam{-900.0, 300.0, 2000.0}, light{700.0, -100.0, 1500.0};
    o.camera.position = cam;
    o.camera.look_at = {0.0, 0.0, 0.0};
    o.camera.up = {0.0, 0.0, 1.0};
    o.camera.fov_deg = 20.0;
    o.camera.rows = o.camera.cols = 64;
    o.plane_size_um = {2000.0, 2000.0};
    o.lights = {ImageLight{LightKind::Point, light}};
    o.lambdas_um = {0.5};
    o.sigma_p_um = 5.0;
    o.prune_tolerance = 0.0;
    const RgbImage image = render_image(flat, prepare_image(flat, o));
    // The mirror point: where the line from the camera to the light's mirror image (z → −z)
    // crosses the plane; its pixel from the pinhole projection.
    const double t = cam[2] / (cam[2] + light[2]);
    const Vec3 m{cam[0] + t * (light[0] - cam[0]), cam[1] + t * (light[1] - cam[1]), 0.0};
    const Vec3 f = unit({-cam[0], -cam[1], -cam[2]});
    const Vec3 up{0.0, 0.0, 1.0};
    const Vec3 right = unit(cross3(f, up));
    const Vec3 u2 = cross3(right, f);
    const Vec3 d{m[0] - cam[0], m[1] - cam[1], m[2] - cam[2]};
    const double along = d[0] * f[0] + d[1] * f[1] + d[2] * f[2];
    const double half = std::tan(10.0 * k_pi / 180.0);
    const double sx = (d[0] * right[0] + d[1] * right[1] + d[2] * right[2]) / along / half;
    const double sy = (d[0] * u2[0] + d[1] * u2[1] + d[2] * u2[2]) / along / half;
    const double col = (sx + 1.0) / 2.0 * 64 - 0.5, row = (1.0 - sy) / 2.0 * 64 - 0.5;
    const test::Brightest best = brightest(image);
    const double peak = best.value;
    ASSERT_GT(peak, 0.0);
    EXPECT_LE(std::abs(best.row - row), 1.0) << "highlight row " << best.row << ", mirror point at " << row;
    EXPECT_LE(std::abs(best.col - col), 1.0) << "highlight column " << best.col << ", mirror point at " << col;
    // Exactly one highlight: every pixel above 1e-2 of the peak is within 4 pixels of the mirror
    // point (the lobe's standard deviation for σ_p = 5 µm is about 1.2 pixels here; further out
    // only the ripple of the window's 3σ_p cut remains, below 5e-3 of the peak).
    int bright = 0;
    for (int r = 0; r < 64; ++r)
        for (int c = 0; c < 64; ++c)
            if (value_at(image, r, c) > 1e-2 * peak) {
                ++bright;
                EXPECT_LE(std::hypot(r - row, c - col), 4.0) << "bright pixel " << r << "," << c;
            }
    EXPECT_GE(bright, 1);
}

// A sinusoidal grating h = A sin(2π x / Λ) along x, a camera straight above, light at normal
// incidence: order m at ω_o,x = m λ / Λ, each wavelength at its own place.
TEST(Image, GratingOrdersWhereTheGratingEquationPutsThem) {
    const int rows = 64, cols = 8, period = 16;
    const double amplitude_um = 0.05;
    std::vector<double> v(std::size_t(rows) * cols);
    for (int i = 0; i < rows; ++i)
        for (int j = 0; j < cols; ++j) v[std::size_t(i) * cols + j] = amplitude_um * std::sin(2 * k_pi * i / period);
    const Heightfield grating(rows, cols, v, 1.0, 1.0);
    const double height = 5000.0;
    ImageOptions o;
    o.camera.position = {0.0, 0.0, height};
    o.camera.look_at = {0.0, 0.0, 0.0};  // straight down: rows follow +x, columns +y
    o.camera.fov_deg = 2.0 * std::atan(0.1) * 180.0 / k_pi;
    o.camera.rows = 240;
    o.camera.cols = 3;
    o.plane_size_um = {4000.0, 4000.0};
    o.lights = {ImageLight{LightKind::Directional, {0.0, 0.0, 1.0}}};
    o.sigma_p_um = 10.0;
    o.prune_tolerance = 0.0;
    // ω_o,x of row r by hand: looking straight down, up is −x, so row r's ray meets the plane at
    // x = −sy · tan(fov/2) · h with sy = 1 − 2(r + ½)/R, and ω_o = (camera − point)/distance.
    auto omega_x = [&](int r) {
        const double sy = 1.0 - (r + 0.5) / o.camera.rows * 2.0;
        const double x = -sy * 0.1 * height;
        return -x / std::sqrt(x * x + height * height);
    };
    double previous_first_order = 0.0;
    for (double lambda : {0.45, 0.65}) {
        o.lambdas_um = {lambda};
        const RgbImage image = render_image(grating, prepare_image(grating, o));
        for (int m : {-2, -1, 1, 2}) {
            const double expected = m * lambda / (period * 1.0);
            // The brightest row within ±0.4 λ/Λ of the predicted order.
            int best = -1;
            double peak = 0.0;
            for (int r = 0; r < o.camera.rows; ++r)
                if (std::abs(omega_x(r) - expected) < 0.4 * lambda / period && value_at(image, r, 1) > peak) {
                    peak = value_at(image, r, 1);
                    best = r;
                }
            ASSERT_GE(best, 0);
            EXPECT_NEAR(omega_x(best), expected, 1e-3 + 0.5 * std::abs(omega_x(1) - omega_x(0)))
                << "order " << m << " at lambda " << lambda;
            // A true maximum, not the window's edge.
            EXPECT_GT(peak, value_at(image, best - 3, 1));
            EXPECT_GT(peak, value_at(image, best + 3, 1));
            if (m == 1) {
                EXPECT_GT(omega_x(best), previous_first_order) << "red diffracts farther than blue";
                previous_first_order = omega_x(best);
            }
        }
    }
    // Under white light (the slices' 8 wavelengths in one image) the first order is a rainbow in
    // its colour sequence: within ω_x in [0.40, 0.70] µm / Λ (no second order there) the blue
    // channel peaks nearest the specular direction, then green, then red, each where the grating
    // equation puts the samples it weighs most (0.36-0.83 µm, 0.067 apart: blue 0.43-0.49, green
    // 0.56, red 0.63-0.70; measured 0.447, 0.553, 0.659 µm).
    o.lambdas_um = spectral_wavelengths_um(8);
    const RgbImage white = render_image(grating, prepare_image(grating, o));
    std::array<double, 3> peak_omega{}, peak{};
    for (int r = 0; r < o.camera.rows; ++r)
        if (omega_x(r) > 0.40 / period && omega_x(r) < 0.70 / period)
            for (int ch = 0; ch < 3; ++ch)
                if (value_at(white, r, 1, ch) > peak[std::size_t(ch)]) {
                    peak[std::size_t(ch)] = value_at(white, r, 1, ch);
                    peak_omega[std::size_t(ch)] = omega_x(r);
                }
    EXPECT_LT(peak_omega[2], peak_omega[1]) << "blue before green";
    EXPECT_LT(peak_omega[1], peak_omega[0]) << "green before red";
    EXPECT_NEAR(peak_omega[2] * period, 0.46, 0.03);
    EXPECT_NEAR(peak_omega[1] * period, 0.56, 0.03);
    EXPECT_NEAR(peak_omega[0] * period, 0.665, 0.035);
}

// One pixel looking at P with a point light: its f_r, the radiance divided by cos θ_i E.
double one_pixel_brdf(const Heightfield& hf, Model model, const Vec3& camera, const Vec3& light, const Vec3& at) {
    ImageOptions o;
    o.camera.position = camera;
    o.camera.look_at = at;
    o.camera.fov_deg = 1.0;
    o.camera.rows = o.camera.cols = 1;
    o.plane_size_um = {1000.0, 1000.0};
    ImageLight l;
    l.kind = LightKind::Point;
    l.vector = light;
    l.power_w = 2.0;
    o.lights = {l};
    o.lambdas_um = {0.6};
    o.model = model;
    o.sigma_p_um = 6.0;
    o.prune_tolerance = 0.0;
    const RgbImage image = render_image(hf, prepare_image(hf, o));
    const Vec3 d{light[0] - at[0], light[1] - at[1], light[2] - at[2]};
    const double dist_m = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) * 1e-6;
    const double irradiance = 2.0 / (4 * k_pi * dist_m * dist_m);
    return value_at(image, 0, 0) / (unit(d)[2] * irradiance);
}

TEST(Image, SwappingLightAndCameraKeepsReciprocalModels) {
    const Heightfield hf = test::random_heightfield(32, 32, 0.4, 5, 1.0, 1.0);
    const Vec3 a{-400.0, 250.0, 900.0}, b{350.0, -150.0, 1200.0}, at{12.0, -7.0, 0.0};
    for (Model model : {Model::ROHS, Model::RGHS, Model::Kirchhoff, Model::OHS}) {
        const double forward = one_pixel_brdf(hf, model, a, b, at);
        const double swapped = one_pixel_brdf(hf, model, b, a, at);
        ASSERT_GT(forward, 0.0);
        if (model == Model::OHS) {
            // Not reciprocal: c1 = cos θ_o / (λ² cos θ_i) changes by (cos θ_a / cos θ_b)².
            const double ca = unit({a[0] - at[0], a[1] - at[1], a[2]})[2];
            const double cb = unit({b[0] - at[0], b[1] - at[1], b[2]})[2];
            EXPECT_NEAR(forward / swapped, (ca * ca) / (cb * cb), 1e-5);
        } else {
            EXPECT_NEAR(forward, swapped, 1e-5 * forward) << to_string(model);
        }
    }
}

TEST(Image, PrunedImageWithinItsStatedBound) {
    const Heightfield hf = test::random_heightfield(64, 64, 0.8, 23, 1.0, 1.0);
    ImageOptions o = looking_at_origin({-300.0, 100.0, 600.0}, 40.0, 24, 24, 1000.0);
    o.lights = {ImageLight{LightKind::Directional, {0.6, 0.1, 0.5}}};
    o.lambdas_um = {0.5};
    o.sigma_p_um = 5.0;
    o.prune_tolerance = 0.0;
    const RgbImage full = render_image(hf, prepare_image(hf, o));
    const double tau = 1e-3;
    o.prune_tolerance = tau;
    const RgbImage pruned = render_image(hf, prepare_image(hf, o));
    // The bound τ c1 A² cos θ_i E per pixel, A = Σ c_k w² from the footprint's own kernels; c1
    // of OHS ≤ 1/(λ² cos θ_i), so the bound on radiance is τ A² / λ² · E.
    double largest_difference = 0.0;
    for (std::size_t k = 0; k < full.data.size(); ++k) {
        const double diff = std::abs(double(full.data[k]) - double(pruned.data[k]));
        largest_difference = std::max(largest_difference, diff);
    }
    const FootprintKernels kernels = footprint_kernels(hf, 500.0, 500.0, 5.0);
    double amplitude = 0.0;
    for (double w : kernels.weight) amplitude += w;
    const double bound = tau * amplitude * amplitude / (0.5 * 0.5);
    const double peak = test::max_abs(std::vector<double>(full.data.begin(), full.data.end()));
    EXPECT_LE(largest_difference, bound * (1 + 1e-6) + 1e-6 * peak);  // + the float images' rounding
    EXPECT_GT(largest_difference, 0.0) << "nothing was pruned: the test would test nothing";
}

// An image loss's gradient against central differences of the double-precision image.
TEST(Image, GradientMatchesFiniteDifferences) {
    const Heightfield hf = test::random_heightfield(16, 12, 0.3, 31, 1.0, 1.0);
    ImageOptions o;
    o.camera.position = {-60.0, 20.0, 150.0};
    o.camera.look_at = {0.0, 0.0, 0.0};
    o.camera.up = {0.0, 0.0, 1.0};
    o.camera.fov_deg = 30.0;
    o.camera.rows = 6;
    o.camera.cols = 7;
    o.plane_size_um = {60.0, 60.0};
    ImageLight light{LightKind::Point, {50.0, -10.0, 120.0}};
    light.spectrum = LightSpectrum::Blackbody;
    light.temperature_k = 3000.0;
    o.lights = {light, ImageLight{LightKind::Directional, {-0.2, 0.3, 1.0}}};
    o.lambdas_um = {0.45, 0.55, 0.65};
    o.model = Model::RGHS;
    o.sigma_p_um = 2.5;
    o.prune_tolerance = 0.0;
    const PreparedImage prepared = prepare_image(hf, o);
    const std::vector<double> w = test::uniform_vector(std::size_t(6 * 7 * 3), -1.0, 1.0, 4);
    auto loss = [&](const Heightfield& h) {
        const std::vector<double> v = render_image_values(h, prepared);
        double sum = 0.0;
        for (std::size_t k = 0; k < v.size(); ++k) sum += w[k] * v[k];
        return sum;
    };
    std::vector<double> gradient;
    image_gradient(hf, prepared, w, gradient);
    const double scale = test::max_abs(gradient);
    ASSERT_GT(scale, 0.0);
    const double h = 1e-5;
    for (std::size_t t : {std::size_t(3), std::size_t(50), std::size_t(97), std::size_t(140), std::size_t(181)}) {
        std::vector<double> up = hf.values(), down = hf.values();
        up[t] += h;
        down[t] -= h;
        const double fd = (loss(hf.with_values(up)) - loss(hf.with_values(down))) / (2.0 * h);
        EXPECT_NEAR(gradient[t], fd, 1e-6 * scale + 1e-6 * std::abs(fd)) << "texel " << t;
    }
}

TEST(Image, BadInputFailsBeforeWork) {
    const Heightfield hf = test::random_heightfield(16, 16, 0.1, 1);
    ImageOptions good;
    good.camera.position = {0.0, 0.0, 500.0};
    good.lights = {ImageLight{LightKind::Point, {100.0, 0.0, 500.0}}};
    good.plane_size_um = {200.0, 200.0};
    good.camera.rows = good.camera.cols = 8;
    EXPECT_NO_THROW(prepare_image(hf, good));
    auto with = [&](auto change) {
        ImageOptions o = good;
        change(o);
        return o;
    };
    test::expect_throw_naming<std::domain_error>(
        [&] {
            prepare_image(hf, with([](ImageOptions& o) { o.camera.position = {0.0, 0.0, -5.0}; }));
        },
        "camera position 0,0,-5 um is inside or below the sample");
    test::expect_throw_naming<std::domain_error>(
        [&] {
            prepare_image(hf, with([](ImageOptions& o) { o.lights[0].vector = {0.0, 0.0, -1.0}; }));
        },
        "point light 0,0,-1 um is behind the sample");
    test::expect_throw_naming<std::domain_error>(
        [&] {
            prepare_image(hf, with([](ImageOptions& o) {
                              o.lights[0].kind = LightKind::Directional;
                              o.lights[0].vector = {1.0, 0.0, -0.2};
                          }));
        },
        "directional light 1,0,-0.2 is behind the sample");
    test::expect_throw_naming<std::domain_error>(
        [&] { prepare_image(hf, with([](ImageOptions& o) { o.camera.fov_deg = 0.0; })); },
        "field of view 0 deg is invalid");
    test::expect_throw_naming<std::domain_error>(
        [&] { prepare_image(hf, with([](ImageOptions& o) { o.sigma_p_um = 1e4; })); }, "too large for the tile");
    // The footprint from the pixel's size: a far camera with few pixels makes huge footprints.
    test::expect_throw_naming<std::domain_error>(
        [&] {
            prepare_image(hf, with([](ImageOptions& o) {
                              o.camera.position = {0.0, 0.0, 1e7};
                              o.camera.fov_deg = 1.0;
                              o.camera.rows = o.camera.cols = 1;
                              o.plane_size_um = {1e6, 1e6};
                          }));
        },
        "pixel footprint");
    // Huge positions (beyond a kilometre) and angles: named, not rendered into a black image.
    test::expect_throw_naming<std::domain_error>(
        [&] {
            prepare_image(hf, with([](ImageOptions& o) { o.camera.position = {0.0, 0.0, 1e300}; }));
        },
        "camera position 0,0,1e+300 um is invalid; expected finite coordinates within +-1e9 um");
    test::expect_throw_naming<std::domain_error>(
        [&] {
            prepare_image(hf, with([](ImageOptions& o) { o.camera.look_at = {2e9, 0.0, 0.0}; }));
        },
        "look-at point 2000000000,0,0 um is invalid");
    test::expect_throw_naming<std::domain_error>(
        [&] {
            prepare_image(hf, with([](ImageOptions& o) { o.lights[0].vector = {1e300, 0.0, 1e300}; }));
        },
        "point light 1e+300,0,1e+300 um is invalid; expected finite coordinates within +-1e9 um");
    test::expect_throw_naming<std::domain_error>(
        [&] { prepare_image(hf, with([](ImageOptions& o) { o.rotation_deg = 1e300; })); },
        "rotation 1e+300 deg is invalid; expected a finite angle within +-1e6 deg");
}

}  // namespace
}  // namespace wavebrdf
