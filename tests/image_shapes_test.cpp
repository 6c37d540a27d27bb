// Spheres and cylinders carrying the heightfield: the mapping's tangent frame against finite
// differences of the mapping itself, a flat sphere's highlight at the mirror point computed by
// hand, a grating brushed along a cylinder's axis diffracting across it where the grating equation
// puts each order, bad shapes refused; disc area lights: a tiny disc is a point light, and the
// quadrature converges to an independent midpoint sum over the disc.
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "image_util.h"
#include "test_util.h"
#include "wavebrdf/constants.h"
#include "wavebrdf/image.h"

namespace wavebrdf {
namespace {

using test::brightest;
using test::cross3;
using test::dot3;
using test::unit;
using test::value_at;
using test::Vec3;

ImageOptions shape(SampleShape kind, double rotation_deg) {
    ImageOptions o;
    o.shape = kind;
    o.radius_um = 300.0;
    o.length_um = 500.0;
    o.plane_size_um = {400.0, 250.0};
    o.rotation_deg = rotation_deg;
    return o;
}

TEST(ImageShapes, TangentFrameOrthonormalAndDerivativesMatchFiniteDifferences) {
    std::mt19937_64 rng(5);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    for (SampleShape kind : {SampleShape::Plane, SampleShape::Sphere, SampleShape::Cylinder})
        for (double rotation : {0.0, 33.0}) {
            const ImageOptions o = shape(kind, rotation);
            for (int trial = 0; trial < 20; ++trial) {
                // Unrotated coordinates (a, b) away from the sphere's poles and seam, inside the
                // plate and the cylinder; the heightfield's (x, y) are them turned by the rotation.
                const bool plane = kind == SampleShape::Plane;
                const double a = 150.0 * u(rng) + (plane ? 200.0 : 0.0), b = 110.0 * u(rng) + (plane ? 125.0 : 0.0);
                const double rho = rotation * k_pi / 180.0;
                const double x = a * std::cos(rho) + b * std::sin(rho), y = -a * std::sin(rho) + b * std::cos(rho);
                const SurfacePoint s = sample_surface_at(o, x, y);
                EXPECT_NEAR(s.x_um, x, 1e-12);
                EXPECT_NEAR(s.y_um, y, 1e-12);
                const Vec3 &tx = s.tangent_x, &ty = s.tangent_y, &n = s.normal;
                EXPECT_NEAR(dot3(tx, tx), 1.0, 1e-14);
                EXPECT_NEAR(dot3(ty, ty), 1.0, 1e-14);
                EXPECT_NEAR(dot3(n, n), 1.0, 1e-14);
                EXPECT_NEAR(dot3(tx, ty), 0.0, 1e-14);
                const Vec3 cross{tx[1] * ty[2] - tx[2] * ty[1], tx[2] * ty[0] - tx[0] * ty[2],
                                 tx[0] * ty[1] - tx[1] * ty[0]};
                for (int k = 0; k < 3; ++k) EXPECT_NEAR(cross[k], n[k], 1e-14) << "right-handed";
                // The normal is the surface's: the sphere's radial direction, the cylinder's away
                // from the axis, the plane's +z.
                Vec3 radial = kind == SampleShape::Sphere     ? unit(s.point)
                              : kind == SampleShape::Cylinder ? unit({0.0, s.point[1], s.point[2]})
                                                              : Vec3{0.0, 0.0, 1.0};
                for (int k = 0; k < 3; ++k) EXPECT_NEAR(n[k], radial[k], 1e-12);
                // Central differences of the mapping (h = 1e-3 µm; error ~h²/R ≪ 1e-7).
                const double h = 1e-3;
                const SurfacePoint xp = sample_surface_at(o, s.x_um + h, s.y_um),
                                   xm = sample_surface_at(o, s.x_um - h, s.y_um),
                                   yp = sample_surface_at(o, s.x_um, s.y_um + h),
                                   ym = sample_surface_at(o, s.x_um, s.y_um - h);
                for (int k = 0; k < 3; ++k) {
                    EXPECT_NEAR((xp.point[k] - xm.point[k]) / (2 * h), s.dp_dx[k], 1e-7);
                    EXPECT_NEAR((yp.point[k] - ym.point[k]) / (2 * h), s.dp_dy[k], 1e-7);
                }
                // The derivatives lie in the tangent plane; without rotation they point along the frame.
                EXPECT_NEAR(dot3(s.dp_dx, n), 0.0, 1e-12);
                EXPECT_NEAR(dot3(s.dp_dy, n), 0.0, 1e-12);
                if (rotation == 0.0) {
                    EXPECT_NEAR(dot3(unit(s.dp_dx), tx), 1.0, 1e-12);
                    EXPECT_NEAR(dot3(unit(s.dp_dy), ty), 1.0, 1e-12);
                }
                // A ray towards the point from outside finds it again, with the same coordinates.
                Vec3 origin, dir;
                for (int k = 0; k < 3; ++k) {
                    origin[k] = s.point[k] + 700.0 * n[k] + 50.0 * tx[k];
                    dir[k] = s.point[k] - origin[k];
                }
                dir = unit(dir);
                SurfacePoint hit;
                double t = 0.0;
                ASSERT_TRUE(sample_ray_hit(o, origin, dir, hit, t));
                for (int k = 0; k < 3; ++k) EXPECT_NEAR(hit.point[k], s.point[k], 1e-9);
                EXPECT_NEAR(hit.x_um, s.x_um, 1e-9);
                EXPECT_NEAR(hit.y_um, s.y_um, 1e-9);
            }
        }
}

// A flat sphere under a directional light seen by an orthographic camera: the one highlight is
// where the normal is the half-vector, p* = R (ω_i + ω_o)/|ω_i + ω_o|, projected by hand.
TEST(ImageShapes, FlatSphereHighlightAtTheMirrorPoint) {
    const Heightfield flat(16, 16, std::vector<double>(256, 0.0), 1.0, 1.0);
    const double R = 200.0;
    const Vec3 L = unit({0.3, 0.2, 1.0}), V = unit({-0.2, 0.1, 1.0});
    ImageOptions o;
    o.shape = SampleShape::Sphere;
    o.radius_um = R;
    o.camera.orthographic = true;
    o.camera.position = {1000.0 * V[0], 1000.0 * V[1], 1000.0 * V[2]};
    o.camera.look_at = {0.0, 0.0, 0.0};
    o.camera.up = {0.0, 0.0, 1.0};
    o.camera.view_width_um = 440.0;
    o.camera.rows = o.camera.cols = 89;
    o.lights = {ImageLight{LightKind::Directional, L}};
    o.lambdas_um = {0.5};
    o.sigma_p_um = 4.0;
    o.prune_tolerance = 0.0;
    const RgbImage image = render_image(flat, prepare_image(flat, o));
    const Vec3 hv = unit({L[0] + V[0], L[1] + V[1], L[2] + V[2]});
    const Vec3 p{R * hv[0], R * hv[1], R * hv[2]};
    // The camera's frame by hand: forward −V, right = forward × up, up' = right × forward.
    const Vec3 f{-V[0], -V[1], -V[2]};
    const Vec3 right = unit({f[1], -f[0], 0.0});  // f × (0, 0, 1)
    const Vec3 up = cross3(right, f);
    const double half = 220.0, pitch = 2 * half / 89;
    const double c_star = (dot3(p, right) + half) / pitch - 0.5, r_star = (half - dot3(p, up)) / pitch - 0.5;
    const test::Brightest best = brightest(image);
    EXPECT_NEAR(best.row, r_star, 1.0);
    EXPECT_NEAR(best.col, c_star, 1.0);
    // One highlight: everything brighter than 1 % of the peak lies within 4 pixels of it.
    for (int r = 0; r < 89; ++r)
        for (int c = 0; c < 89; ++c)
            if (value_at(image, r, c) > 1e-2 * best.value) {
                EXPECT_LE(std::hypot(r - r_star, c - c_star), 4.0) << r << "," << c;
            }
}

// Grooves along a cylinder's axis (heights varying with y only, the circumference at rotation 0)
// under a light in the y-z plane, seen from straight above: at angle ψ about the axis the surface
// frame has ω_i,y = sin(α − ψ), ω_o,y = −sin ψ, ω_x = 0, so order m sits where
// sin(α − ψ) − sin ψ = mλ/Λ, i.e. ψ_m = α/2 − asin(mλ / (2Λ cos(α/2))), at y = R sin ψ — a streak
// across the axis, the same in every row along it.
TEST(ImageShapes, BrushedCylinderDiffractsAcrossItsAxis) {
    const int rows = 8, cols = 64, period = 8;
    std::vector<double> v(std::size_t(rows) * cols);
    for (int i = 0; i < rows; ++i)
        for (int j = 0; j < cols; ++j) v[std::size_t(i) * cols + j] = 0.05 * std::sin(2 * k_pi * j / period);
    const Heightfield grating(rows, cols, v, 1.0, 1.0);
    const double R = 500.0, alpha = 20.0 * k_pi / 180.0;
    ImageOptions o;
    o.shape = SampleShape::Cylinder;
    o.radius_um = R;
    o.length_um = 400.0;
    o.camera.orthographic = true;
    o.camera.position = {0.0, 80.0, 2000.0};
    o.camera.look_at = {0.0, 80.0, 0.0};  // straight down: rows follow +x (the axis), columns +y
    o.camera.rows = 4;
    o.camera.cols = 200;
    o.camera.view_width_um = 8.0;  // 2 µm pixels; columns cover y from −120 to 280
    o.lights = {ImageLight{LightKind::Directional, {0.0, std::sin(alpha), std::cos(alpha)}}};
    o.sigma_p_um = 10.0;
    o.prune_tolerance = 0.0;
    auto y_of = [&](int c) { return 80.0 + ((c + 0.5) / o.camera.cols * 2.0 - 1.0) * 200.0; };
    double previous = 0.0;
    for (double lambda : {0.45, 0.65}) {
        o.lambdas_um = {lambda};
        const RgbImage image = render_image(grating, prepare_image(grating, o));
        for (int m : {-1, 0, 1}) {
            const double psi = alpha / 2 - std::asin(m * lambda / (2.0 * period * std::cos(alpha / 2)));
            const double y = R * std::sin(psi);
            int best = -1;
            double peak = 0.0;
            for (int c = 0; c < o.camera.cols; ++c)
                if (std::abs(y_of(c) - y) < 6.0 && value_at(image, 1, c) > peak) {
                    peak = value_at(image, 1, c);
                    best = c;
                }
            ASSERT_GE(best, 3);
            EXPECT_NEAR(y_of(best), y, 2.0) << "order " << m << " at lambda " << lambda;  // within a pixel
            EXPECT_GT(peak, 3.0 * value_at(image, 1, best - 3)) << "a true maximum";
            EXPECT_GT(peak, 3.0 * value_at(image, 1, best + 3));
            if (m == 1) {
                EXPECT_GT(std::abs(y_of(best) - R * std::sin(alpha / 2)), previous) << "red farther than blue";
                previous = std::abs(y_of(best) - R * std::sin(alpha / 2));
            }
        }
        // Along the axis nothing changes: every row is the same streak.
        for (int r = 0; r < o.camera.rows; ++r)
            for (int c = 0; c < o.camera.cols; ++c)
                EXPECT_NEAR(value_at(image, r, c), value_at(image, 1, c), 1e-6 * value_at(image, 1, c) + 1e-30);
    }
}

TEST(ImageShapes, BadShapesFailBeforeWork) {
    const Heightfield hf = test::random_heightfield(16, 16, 0.1, 1);
    ImageOptions good;
    good.shape = SampleShape::Sphere;
    good.radius_um = 100.0;
    good.length_um = 300.0;
    good.camera.position = {0.0, 0.0, 500.0};
    good.lights = {ImageLight{LightKind::Point, {100.0, 0.0, 500.0}}};
    good.camera.rows = good.camera.cols = 8;
    good.sigma_p_um = 3.0;
    EXPECT_NO_THROW(prepare_image(hf, good));
    auto with = [&](auto change) {
        ImageOptions o = good;
        change(o);
        return o;
    };
    test::expect_throw_naming<std::domain_error>(
        [&] {
            prepare_image(hf, with([](ImageOptions& o) { o.camera.position = {0.0, 60.0, 50.0}; }));
        },
        "camera position 0,60,50 um is inside the sphere of radius 100 um");
    test::expect_throw_naming<std::domain_error>(
        [&] { prepare_image(hf, with([](ImageOptions& o) { o.radius_um = 0.0; })); }, "sphere radius 0 um is invalid");
    test::expect_throw_naming<std::domain_error>(
        [&] {
            prepare_image(hf, with([](ImageOptions& o) { o.lights[0].vector = {10.0, 0.0, -20.0}; }));
        },
        "point light 10,0,-20 um is inside the sphere");
    test::expect_throw_naming<std::domain_error>(
        [&] {
            prepare_image(hf, with([](ImageOptions& o) {
                              o.shape = SampleShape::Cylinder;
                              o.camera.position = {900.0, 0.0, 99.0};
                          }));
        },
        "camera position 900,0,99 um is inside the cylinder of radius 100 um");
    test::expect_throw_naming<std::domain_error>(
        [&] {
            prepare_image(hf, with([](ImageOptions& o) {
                              o.shape = SampleShape::Cylinder;
                              o.length_um = -1.0;
                          }));
        },
        "cylinder length -1 um is invalid");
    test::expect_throw_naming<std::domain_error>(
        [&] {
            prepare_image(hf, with([](ImageOptions& o) {
                              o.lights[0].kind = LightKind::Directional;
                              o.lights[0].vector = {0.0, 0.0, 0.0};
                          }));
        },
        "directional light 0,0,0 has no direction");
    // Below the plane is fine for a sphere: a light under it lights its lower half.
    EXPECT_NO_THROW(prepare_image(hf, with([](ImageOptions& o) { o.lights[0].vector = {0.0, 0.0, -500.0}; })));
}

// One pixel looking at `at` (its ray passes through it) lit by `lights`.
double one_pixel(const Heightfield& hf, const Vec3& at, const std::vector<ImageLight>& lights) {
    ImageOptions o;
    o.camera.position = {-300.0, 200.0, 900.0};
    o.camera.look_at = at;
    o.camera.fov_deg = 0.5;
    o.camera.rows = o.camera.cols = 1;
    o.plane_size_um = {1000.0, 1000.0};
    o.lights = lights;
    o.lambdas_um = {0.55};
    o.sigma_p_um = 4.0;
    o.prune_tolerance = 0.0;
    return value_at(render_image(hf, prepare_image(hf, o)), 0, 0);
}

ImageLight disc(const Vec3& centre, double radius, int order) {
    ImageLight l;
    l.kind = LightKind::Disc;
    l.vector = centre;
    l.radius_um = radius;
    l.disc_order = order;
    l.power_w = 3.0;
    return l;
}

// A tiny Lambertian disc of power P is a point emitter of intensity P cos θ_e / π, θ_e from its
// normal (towards the origin): a point light of power 4 P cos θ_e, computed by hand at the pixel.
TEST(ImageDiscLight, TinyDiscEqualsThePointLight) {
    const Heightfield hf = test::random_heightfield(32, 32, 0.3, 9, 1.0, 1.0);
    const Vec3 centre{250.0, -100.0, 600.0};
    for (const Vec3& at : {Vec3{10.0, 5.0, 0.0}, Vec3{-40.0, 20.0, 0.0}, Vec3{30.0, -60.0, 0.0}}) {
        const Vec3 nd = unit({-centre[0], -centre[1], -centre[2]});
        const Vec3 out = unit({at[0] - centre[0], at[1] - centre[1], at[2] - centre[2]});
        ImageLight point;
        point.kind = LightKind::Point;
        point.vector = centre;
        point.power_w = 4.0 * 3.0 * dot3(nd, out);
        const double expected = one_pixel(hf, at, {point});
        ASSERT_GT(expected, 0.0);
        for (int order : {1, 3}) EXPECT_NEAR(one_pixel(hf, at, {disc(centre, 1e-3, order)}), expected, 1e-8 * expected);
    }
}

// A disc whose angular size spans the glint's lobe: the product rule converges with its order to
// an independent reference, the disc cut into 60 equal-area rings × 120 angles (midpoint rule,
// 7200 cells), each cell a point light of power 4 π L_e cos θ_e A_cell (its Lambertian element's
// intensity towards the pixel, θ_e by hand).
TEST(ImageDiscLight, QuadratureConvergesToAFineMidpointReference) {
    const Heightfield hf = test::random_heightfield(32, 32, 0.3, 9, 1.0, 1.0);
    const Vec3 centre{300.0, -200.0, 900.0}, at{5.0, -3.0, 0.0};
    const double r = 40.0, power = 3.0;
    const double radiance = power / (k_pi * k_pi * r * r);  // W/(µm² sr) per unit power area
    const Vec3 nd = unit({-centre[0], -centre[1], -centre[2]});
    const Vec3 helper{1.0, 0.0, 0.0};
    const Vec3 u = unit({nd[1] * helper[2] - nd[2] * helper[1], nd[2] * helper[0] - nd[0] * helper[2],
                         nd[0] * helper[1] - nd[1] * helper[0]});
    const Vec3 v{nd[1] * u[2] - nd[2] * u[1], nd[2] * u[0] - nd[0] * u[2], nd[0] * u[1] - nd[1] * u[0]};
    const int rings = 60, angles = 120;
    const double cell = k_pi * r * r / (rings * angles);
    double reference = 0.0;
    std::vector<ImageLight> batch;
    for (int i = 0; i < rings; ++i)
        for (int j = 0; j < angles; ++j) {
            const double rho = r * std::sqrt((i + 0.5) / rings), phi = 2 * k_pi * (j + 0.5) / angles;
            ImageLight l;
            l.kind = LightKind::Point;
            for (int k = 0; k < 3; ++k)
                l.vector[k] = centre[k] + rho * std::cos(phi) * u[k] + rho * std::sin(phi) * v[k];
            const Vec3 out = unit({at[0] - l.vector[0], at[1] - l.vector[1], at[2] - l.vector[2]});
            l.power_w = 4.0 * k_pi * radiance * dot3(nd, out) * cell;
            batch.push_back(l);
            if (batch.size() == 64) {
                reference += one_pixel(hf, at, batch);
                batch.clear();
            }
        }
    if (!batch.empty()) reference += one_pixel(hf, at, batch);
    ASSERT_GT(reference, 0.0);
    // The disc matters: it differs from a point light of the same power at its centre.
    ImageLight point;
    point.kind = LightKind::Point;
    point.vector = centre;
    point.power_w = 4.0 * power * dot3(nd, unit({at[0] - centre[0], at[1] - centre[1], at[2] - centre[2]}));
    const double as_point = one_pixel(hf, at, {point});
    EXPECT_GT(std::abs(as_point - reference), 0.05 * reference);
    double previous = std::abs(as_point - reference);
    for (int order : {1, 2, 4, 8, 12}) {
        const double error = std::abs(one_pixel(hf, at, {disc(centre, r, order)}) - reference);
        std::printf("disc order %d: relative error %.3g\n", order, error / reference);
        if (order <= 4) {
            EXPECT_LT(error, previous) << "order " << order;
        }
        previous = std::min(previous, error);
        if (order >= 8) {  // the reference's own midpoint error is about 2e-5
            EXPECT_LT(error, 1e-4 * reference) << "order " << order;
        }
    }
}

TEST(ImageDiscLight, BadDiscsFailBeforeWork) {
    const Heightfield hf = test::random_heightfield(16, 16, 0.1, 1);
    ImageOptions o;
    o.camera.position = {0.0, 0.0, 500.0};
    o.plane_size_um = {200.0, 200.0};
    o.camera.rows = o.camera.cols = 4;
    o.sigma_p_um = 3.0;
    o.lights = {disc({100.0, 0.0, 500.0}, 0.0, 4)};
    test::expect_throw_naming<std::domain_error>([&] { prepare_image(hf, o); }, "disc light radius 0 um is invalid");
    o.lights = {disc({300.0, 0.0, 20.0}, 50.0, 4)};
    test::expect_throw_naming<std::domain_error>([&] { prepare_image(hf, o); },
                                                 "disc light 300,0,20 um of radius 50 um reaches the plane");
    o.lights = {disc({100.0, 0.0, 500.0}, 10.0, 0)};
    test::expect_throw_naming<std::domain_error>([&] { prepare_image(hf, o); }, "disc light order 0 is out of range");
    o.shape = SampleShape::Sphere;
    o.radius_um = 100.0;
    o.lights = {disc({0.0, 0.0, 150.0}, 60.0, 4)};
    test::expect_throw_naming<std::domain_error>([&] { prepare_image(hf, o); },
                                                 "disc light 0,0,150 um of radius 60 um reaches into the sample");
}

}  // namespace
}  // namespace wavebrdf
