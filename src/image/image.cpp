// Camera images (image.h): the geometry of every pixel (its ray, where it meets the sample, its
// footprint and its directions in the surface's frame), then the point-evaluation engine
// (point_eval.h) row by row, weighted into radiance by the lights and the spectral mix.
#include "wavebrdf/image.h"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfOutputFile.h>
#include <ImfStringAttribute.h>

#include "core/text.h"
#include "wavebrdf/constants.h"
#include "wavebrdf/gabor.h"
#include "wavebrdf/interrupt.h"
#include "wavebrdf/memory.h"
#include "wavebrdf/point_eval.h"
#include "wavebrdf/spectrum.h"
#include "wavebrdf/version.h"

namespace wavebrdf {

const char* const k_image_unit =
    "radiance in W/(m^2 sr), linear sRGB (D65): sum over lights and wavelengths of the spectral mix of "
    "f_r(omega_i, omega_o) [1/sr] * cos(theta_i) * E_light [W/m^2]; one wavelength: R = G = B";

namespace {

using Vec3 = std::array<double, 3>;

Vec3 sub(const Vec3& a, const Vec3& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
Vec3 add(const Vec3& a, const Vec3& b) { return {a[0] + b[0], a[1] + b[1], a[2] + b[2]}; }
Vec3 mul(const Vec3& a, double s) { return {a[0] * s, a[1] * s, a[2] * s}; }
double dot(const Vec3& a, const Vec3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
Vec3 cross(const Vec3& a, const Vec3& b) {
    return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
double norm(const Vec3& a) { return std::sqrt(dot(a, a)); }
// a / |a|, scaled by its largest component first so that a direction given with huge or tiny
// components (a directional light at 1e300,0,1e300) neither overflows nor underflows.
Vec3 normalised(const Vec3& a) {
    const double largest = std::max({std::abs(a[0]), std::abs(a[1]), std::abs(a[2])});
    const Vec3 b = largest > 0.0 && std::isfinite(largest) ? Vec3{a[0] / largest, a[1] / largest, a[2] / largest} : a;
    return mul(b, 1.0 / norm(b));
}

std::string vec_text(const Vec3& v) {
    return format_shortest(v[0]) + "," + format_shortest(v[1]) + "," + format_shortest(v[2]);
}

bool finite(const Vec3& v) { return std::isfinite(v[0]) && std::isfinite(v[1]) && std::isfinite(v[2]); }

// A position in the scene: finite and within a kilometre of the origin on each axis (a camera or
// light beyond that sees or lights the sample only as a rounding error, a black image).
constexpr double k_max_coordinate_um = 1e9;
bool position_in_range(const Vec3& v) {
    return finite(v) && std::abs(v[0]) <= k_max_coordinate_um && std::abs(v[1]) <= k_max_coordinate_um &&
           std::abs(v[2]) <= k_max_coordinate_um;
}
const char* const k_position_expected = " um is invalid; expected finite coordinates within +-1e9 um";

// The camera's orthonormal frame: forward, right (image columns), up (towards row 0).
struct CameraFrame {
    Vec3 origin, forward, right, up;
    double half_height;  // pinhole: tan(fov/2); orthographic: half the view width, µm
    double half_width;
    bool orthographic;
    int rows, cols;

    // The ray of pixel (r, c) at its centre: origin and unit direction.
    void ray(int r, int c, Vec3& o, Vec3& d) const {
        const double sx = ((c + 0.5) / cols * 2.0 - 1.0) * half_width;
        const double sy = (1.0 - (r + 0.5) / rows * 2.0) * half_height;
        if (orthographic) {
            o = add(origin, add(mul(right, sx), mul(up, sy)));
            d = forward;
        } else {
            o = origin;
            d = normalised(add(forward, add(mul(right, sx), mul(up, sy))));
        }
    }
};

CameraFrame camera_frame(const ImageOptions& options) {
    const ImageCamera& cam = options.camera;
    CameraFrame f;
    f.origin = cam.position;
    f.forward = normalised(sub(cam.look_at, cam.position));
    Vec3 up = cam.up;
    if (norm(up) == 0.0) {
        up = {0.0, 0.0, 1.0};
        if (std::abs(dot(up, f.forward)) > 0.999) up = {-1.0, 0.0, 0.0};
    }
    f.right = normalised(cross(f.forward, up));
    f.up = cross(f.right, f.forward);
    f.orthographic = cam.orthographic;
    f.rows = cam.rows;
    f.cols = cam.cols;
    const double aspect = double(cam.cols) / double(cam.rows);
    if (cam.orthographic) {
        const double width = cam.view_width_um > 0.0               ? cam.view_width_um
                             : options.shape == SampleShape::Plane ? options.plane_size_um[0]
                             : options.shape == SampleShape::Sphere
                                 ? 2.0 * options.radius_um
                                 : std::max(options.length_um, 2.0 * options.radius_um);
        f.half_height = 0.5 * width;
    } else {
        f.half_height = std::tan(0.5 * cam.fov_deg * k_pi / 180.0);
    }
    f.half_width = f.half_height * aspect;
    return f;
}

// One pixel's geometry on the sample: whether it hits it, the footprint centre in the
// heightfield's coordinates, the surface frame there, ω_o in that frame, the hit point and σ_p.
struct PixelGeometry {
    bool hit = false;
    Vec3 point{};
    double x_um = 0.0, y_um = 0.0;
    Vec3 tx{}, ty{}, n{};
    std::array<double, 2> omega_o{{0.0, 0.0}};
    double sigma_p_um = 0.0;
};

// The grazing floor of a curved sample's footprint: σ_p from the pixel's area with cos θ_o at
// least this (at a silhouette the area over cos θ_o grows without bound, while the surface
// curving away keeps the patch the pixel really sees finite).
constexpr double k_min_cos_curved = 0.125;

// The unrotated mapping (a, b) → point with its unit derivative directions e1, e2 and their
// lengths (the metric's scale factors), then turned by the rotation.
SurfacePoint surface_from_ab(const ImageOptions& o, double a, double b, double cos_r, double sin_r) {
    Vec3 p, e1, e2;
    double s1 = 1.0, s2 = 1.0;
    switch (o.shape) {
        case SampleShape::Plane:
            p = {a - 0.5 * o.plane_size_um[0], b - 0.5 * o.plane_size_um[1], 0.0};
            e1 = {1.0, 0.0, 0.0};
            e2 = {0.0, 1.0, 0.0};
            break;
        case SampleShape::Sphere: {
            const double R = o.radius_um, phi = a / R, beta = b / R;
            const double cp = std::cos(phi), sp = std::sin(phi), cb = std::cos(beta), sb = std::sin(beta);
            p = {R * cb * sp, R * sb, R * cb * cp};
            e1 = {cp, 0.0, -sp};
            e2 = {-sb * sp, cb, -sb * cp};
            s1 = cb;
            break;
        }
        case SampleShape::Cylinder: {
            const double R = o.radius_um, psi = b / R, c = std::cos(psi), s = std::sin(psi);
            p = {a, R * s, R * c};
            e1 = {1.0, 0.0, 0.0};
            e2 = {0.0, c, -s};
            break;
        }
    }
    SurfacePoint q;
    q.point = p;
    q.x_um = a * cos_r + b * sin_r;
    q.y_um = -a * sin_r + b * cos_r;
    q.tangent_x = add(mul(e1, cos_r), mul(e2, sin_r));
    q.tangent_y = add(mul(e1, -sin_r), mul(e2, cos_r));
    q.normal = cross(e1, e2);
    q.dp_dx = add(mul(e1, s1 * cos_r), mul(e2, s2 * sin_r));
    q.dp_dy = add(mul(e1, -s1 * sin_r), mul(e2, s2 * cos_r));
    return q;
}

// The pixel's area on the surface: its solid angle times t² over cos θ_o (pinhole), its
// cross-section over cos θ_o (orthographic); σ_p is half the square root of it.
PixelGeometry pixel_geometry(const CameraFrame& cam, const ImageOptions& options, int r, int c) {
    PixelGeometry g;
    Vec3 o, d;
    cam.ray(r, c, o, d);
    SurfacePoint sp;
    double t = 0.0;
    if (!sample_ray_hit(options, o, d, sp, t)) return g;
    const Vec3 wo = mul(d, -1.0);
    double cos_o = dot(wo, sp.normal);
    if (!(cos_o > 0.0)) return g;
    g.hit = true;
    g.point = sp.point;
    g.x_um = sp.x_um;
    g.y_um = sp.y_um;
    g.tx = sp.tangent_x;
    g.ty = sp.tangent_y;
    g.n = sp.normal;
    g.omega_o = {dot(wo, g.tx), dot(wo, g.ty)};
    if (options.sigma_p_um > 0.0) {
        g.sigma_p_um = options.sigma_p_um;
    } else {
        if (options.shape != SampleShape::Plane) cos_o = std::max(cos_o, k_min_cos_curved);
        double area;
        if (cam.orthographic) {
            const double side = 2.0 * cam.half_height / cam.rows;
            area = side * side / cos_o;
        } else {
            const double pitch = 2.0 * cam.half_height / cam.rows;  // per unit forward distance
            const double cos_a = dot(d, cam.forward);
            area = pitch * pitch * cos_a * cos_a * cos_a * t * t / cos_o;
        }
        g.sigma_p_um = 0.5 * std::sqrt(area);
    }
    return g;
}

// Gauss–Legendre nodes and weights on [−1, 1] (Newton on P_n from the Chebyshev guess).
void gauss_legendre(int n, std::vector<double>& t, std::vector<double>& w) {
    t.assign(std::size_t(n), 0.0);
    w.assign(std::size_t(n), 0.0);
    for (int i = 0; i < n; ++i) {
        double x = std::cos(k_pi * (i + 0.75) / (n + 0.5)), dp = 1.0;
        for (int it = 0; it < 100; ++it) {
            double p0 = 1.0, p1 = x;
            for (int k = 2; k <= n; ++k) {
                const double p2 = ((2.0 * k - 1.0) * x * p1 - (k - 1.0) * p0) / k;
                p0 = p1;
                p1 = p2;
            }
            dp = n * (x * p1 - p0) / (x * x - 1.0);
            const double step = p1 / dp;
            x -= step;
            if (std::abs(step) < 1e-15) break;
        }
        t[std::size_t(i)] = x;
        w[std::size_t(i)] = 2.0 / ((1.0 - x * x) * dp * dp);
    }
}

// The disc's unit normal: towards the origin.
Vec3 disc_normal(const ImageLight& light) { return mul(light.vector, -1.0 / norm(light.vector)); }

// A point emitter: a point or directional light, or one node of a disc light with its share
// of the disc's radiant intensity (W/sr along its normal) and the disc's normal.
struct Emitter {
    LightKind kind;
    Vec3 vector;
    double scale;  // point: power; directional: irradiance; disc node: P · (weight / π r²) / π
    Vec3 facing;
    std::size_t light;
};

// The light's direction towards it from `p`, and its irradiance on a surface facing it (W/m²).
void light_at(const Emitter& light, const Vec3& p, Vec3& omega, double& irradiance) {
    if (light.kind == LightKind::Disc) {
        const Vec3 to = sub(light.vector, p);
        const double d = norm(to);
        omega = mul(to, 1.0 / d);
        const double d_m = d * 1e-6;
        irradiance = light.scale * std::max(0.0, -dot(light.facing, omega)) / (d_m * d_m);
        return;
    }
    if (light.kind == LightKind::Directional) {
        omega = normalised(light.vector);
        irradiance = light.scale;
    } else {
        const Vec3 to = sub(light.vector, p);
        const double d = norm(to);
        omega = mul(to, 1.0 / d);
        const double d_m = d * 1e-6;
        irradiance = light.scale / (4.0 * k_pi * d_m * d_m);
    }
}

// S(λ) at the samples, mean 1.
std::vector<double> light_spectrum(const ImageLight& light, const std::vector<double>& lambdas) {
    std::vector<double> s(lambdas.size(), 1.0);
    if (light.spectrum == LightSpectrum::Blackbody && lambdas.size() > 1) {
        // Planck: B ∝ λ^−5 / (e^{hc/(λkT)} − 1), hc/k = 14387.768775 µm·K (from the SI's exact h,
        // c and k; 14387.77 put the weights 5e-8 off).
        double mean = 0.0;
        for (std::size_t l = 0; l < lambdas.size(); ++l) {
            const double x = 14387.768775039337 / (lambdas[l] * light.temperature_k);
            s[l] = std::pow(lambdas[l], -5.0) / std::expm1(x);
            mean += s[l];
        }
        mean /= double(lambdas.size());
        for (double& v : s) v /= mean;
    }
    return s;
}

void require(bool ok, const std::string& message) {
    if (!ok) throw std::domain_error(message);
}

}  // namespace

std::array<double, 3> orbit_about_z(const std::array<double, 3>& p, double degrees) {
    const double a = degrees * k_pi / 180.0, c = std::cos(a), s = std::sin(a);
    return {c * p[0] - s * p[1], s * p[0] + c * p[1], p[2]};
}

void disc_light_nodes(const ImageLight& light, std::vector<std::array<double, 3>>& positions,
                      std::vector<double>& weights) {
    const int n = light.disc_order;
    std::vector<double> t, w;
    gauss_legendre(n, t, w);
    const Vec3 nd = disc_normal(light);
    const Vec3 helper = std::abs(nd[0]) < 0.9 ? Vec3{1.0, 0.0, 0.0} : Vec3{0.0, 1.0, 0.0};
    const Vec3 u = normalised(cross(nd, helper)), v = cross(nd, u);
    const double r = light.radius_um;
    positions.clear();
    weights.clear();
    // ∫∫ g ρ dρ dφ: ρ = r (1 + t)/2 with weight w r/2 · ρ, φ at 2n midpoints with weight π/n.
    for (int i = 0; i < n; ++i) {
        const double rho = 0.5 * r * (1.0 + t[std::size_t(i)]);
        const double radial = w[std::size_t(i)] * 0.5 * r * rho;
        for (int j = 0; j < 2 * n; ++j) {
            const double phi = (j + 0.5) * k_pi / n;
            positions.push_back(add(light.vector, add(mul(u, rho * std::cos(phi)), mul(v, rho * std::sin(phi)))));
            weights.push_back(radial * k_pi / n);
        }
    }
}

SurfacePoint sample_surface_at(const ImageOptions& o, double x_um, double y_um) {
    const double rho = o.rotation_deg * k_pi / 180.0, cr = std::cos(rho), sr = std::sin(rho);
    return surface_from_ab(o, x_um * cr - y_um * sr, x_um * sr + y_um * cr, cr, sr);
}

bool sample_ray_hit(const ImageOptions& o, const std::array<double, 3>& origin, const std::array<double, 3>& d,
                    SurfacePoint& hit, double& t) {
    double a = 0.0, b = 0.0;
    if (o.shape == SampleShape::Plane) {
        if (!(d[2] < 0.0)) return false;
        t = -origin[2] / d[2];
        if (!(t > 0.0)) return false;
        const Vec3 p = add(origin, mul(d, t));
        if (std::abs(p[0]) > 0.5 * o.plane_size_um[0] || std::abs(p[1]) > 0.5 * o.plane_size_um[1]) return false;
        a = p[0] + 0.5 * o.plane_size_um[0];
        b = p[1] + 0.5 * o.plane_size_um[1];
    } else {
        const double R = o.radius_um;
        // |q|² = R² with q the point (sphere) or its (y, z) part (cylinder): the entering root.
        const bool sphere = o.shape == SampleShape::Sphere;
        const double A = sphere ? 1.0 : d[1] * d[1] + d[2] * d[2];
        const double B = sphere ? dot(origin, d) : origin[1] * d[1] + origin[2] * d[2];
        const double C = (sphere ? dot(origin, origin) : origin[1] * origin[1] + origin[2] * origin[2]) - R * R;
        if (!(C > 0.0) || !(A > 0.0)) return false;
        const double disc = B * B - A * C;
        if (!(disc >= 0.0)) return false;
        // The entering root in the cancellation-free form C / (−B + √disc).
        const double denom = -B + std::sqrt(disc);
        if (!(denom > 0.0)) return false;
        t = C / denom;
        if (!(t > 0.0)) return false;
        const Vec3 p = add(origin, mul(d, t));
        if (sphere) {
            a = R * std::atan2(p[0], p[2]);
            b = R * std::asin(std::clamp(p[1] / R, -1.0, 1.0));
        } else {
            if (std::abs(p[0]) > 0.5 * o.length_um) return false;
            a = p[0];
            b = R * std::atan2(p[1], p[2]);
        }
    }
    const double rho = o.rotation_deg * k_pi / 180.0;
    hit = surface_from_ab(o, a, b, std::cos(rho), std::sin(rho));
    return true;
}

PreparedImage prepare_image(const Heightfield& heightfield, const ImageOptions& options) {
    const ImageCamera& cam = options.camera;
    require(position_in_range(cam.position), "camera position " + vec_text(cam.position) + k_position_expected);
    require(position_in_range(cam.look_at), "look-at point " + vec_text(cam.look_at) + k_position_expected);
    require(finite(cam.up), "camera up " + vec_text(cam.up) + " is not finite");
    const bool plane = options.shape == SampleShape::Plane;
    const bool sphere = options.shape == SampleShape::Sphere;
    if (!plane) {
        require(std::isfinite(options.radius_um) && options.radius_um > 0.0 && options.radius_um <= 1e9,
                std::string(sphere ? "sphere" : "cylinder") + " radius " + format_shortest(options.radius_um) +
                    " um is invalid; expected 0 < radius <= 1e9");
        if (!sphere)
            require(
                std::isfinite(options.length_um) && options.length_um > 0.0 && options.length_um <= 1e9,
                "cylinder length " + format_shortest(options.length_um) + " um is invalid; expected 0 < length <= 1e9");
    }
    // Outside a sphere: the distance from its centre; outside a cylinder: from its axis (x).
    auto distance = [&](const Vec3& p) { return sphere ? norm(p) : std::sqrt(p[1] * p[1] + p[2] * p[2]); };
    auto where = [&] {
        return sphere ? " um is inside the sphere of radius " + format_shortest(options.radius_um) +
                            " um; expected a distance from the origin > the radius"
                      : " um is inside the cylinder of radius " + format_shortest(options.radius_um) +
                            " um; expected a distance from the x axis > the radius";
    };
    if (plane)
        require(cam.position[2] > 0.0, "camera position " + vec_text(cam.position) +
                                           " um is inside or below the sample; expected z > 0 (above the plane)");
    else
        require(distance(cam.position) > options.radius_um, "camera position " + vec_text(cam.position) + where());
    const Vec3 view = sub(cam.look_at, cam.position);
    require(norm(view) > 0.0, "look-at point " + vec_text(cam.look_at) +
                                  " equals the camera position; expected a "
                                  "point the camera looks towards");
    if (norm(cam.up) > 0.0)
        require(norm(cross(normalised(view), normalised(cam.up))) > 1e-9,
                "camera up " + vec_text(cam.up) + " is parallel to the viewing direction; expected another up");
    require(cam.rows >= 1 && cam.rows <= 8192 && cam.cols >= 1 && cam.cols <= 8192,
            "resolution " + std::to_string(cam.rows) + "x" + std::to_string(cam.cols) +
                " is out of range; expected 1 to 8192 per side");
    if (cam.orthographic) {
        require(std::isfinite(cam.view_width_um) && cam.view_width_um >= 0.0,
                "view width " + format_shortest(cam.view_width_um) + " um is invalid; expected > 0 (0: the plane's)");
    } else {
        require(std::isfinite(cam.fov_deg) && cam.fov_deg > 0.0 && cam.fov_deg < 180.0,
                "field of view " + format_shortest(cam.fov_deg) + " deg is invalid; expected 0 < fov < 180");
    }
    for (int a = 0; a < 2; ++a)
        require(std::isfinite(options.plane_size_um[a]) && options.plane_size_um[a] > 0.0 &&
                    options.plane_size_um[a] <= 1e9,
                "plane size " + format_shortest(options.plane_size_um[a]) + " um is invalid; expected 0 < size <= 1e9");
    require(std::isfinite(options.rotation_deg) && std::abs(options.rotation_deg) <= 1e6,
            "rotation " + format_shortest(options.rotation_deg) +
                " deg is invalid; expected a finite angle within +-1e6 deg");
    require(!options.lights.empty(), "no light; expected at least one (--point-light, --directional-light or --disc-light)");
    require(options.lights.size() <= 64,
            std::to_string(options.lights.size()) + " lights are too many; expected at most 64");
    for (const ImageLight& light : options.lights) {
        const std::string what = light.kind == LightKind::Point         ? "point light "
                                 : light.kind == LightKind::Directional ? "directional light "
                                                                        : "disc light ";
        if (light.kind == LightKind::Directional)
            require(finite(light.vector), what + vec_text(light.vector) + " is not finite");
        else
            require(position_in_range(light.vector), what + vec_text(light.vector) + k_position_expected);
        if (light.kind == LightKind::Disc) {
            require(
                std::isfinite(light.radius_um) && light.radius_um > 0.0 && light.radius_um <= 1e9,
                "disc light radius " + format_shortest(light.radius_um) + " um is invalid; expected 0 < radius <= 1e9");
            require(light.disc_order >= 1 && light.disc_order <= 32,
                    "disc light order " + std::to_string(light.disc_order) + " is out of range; expected 1 to 32");
            require(norm(light.vector) > 0.0,
                    what + vec_text(light.vector) + " um is at the origin; expected a centre that can face it");
            // Every point of the disc outside the sample: its lowest point above a plate; its
            // centre farther than R + r from a sphere's centre or a cylinder's axis.
            const Vec3 nd = disc_normal(light);
            const double lowest = light.vector[2] - light.radius_um * std::sqrt(std::max(0.0, 1.0 - nd[2] * nd[2]));
            if (plane)
                require(lowest > 0.0, what + vec_text(light.vector) + " um of radius " +
                                          format_shortest(light.radius_um) +
                                          " um reaches the plane or below it; expected every point at z > 0");
            else
                require(distance(light.vector) > options.radius_um + light.radius_um,
                        what + vec_text(light.vector) + " um of radius " + format_shortest(light.radius_um) +
                            " um reaches into the sample; expected its centre farther than the sample's radius "
                            "plus the disc's");
        } else if (plane)
            require(light.vector[2] > 0.0, what + vec_text(light.vector) +
                                               (light.kind == LightKind::Point ? " um" : "") +
                                               " is behind the sample; expected z > 0 (above the plane)");
        else if (light.kind == LightKind::Point)
            require(distance(light.vector) > options.radius_um, what + vec_text(light.vector) + where());
        else
            require(norm(light.vector) > 0.0, what + vec_text(light.vector) + " has no direction; expected X,Y,Z != 0");
        require(std::isfinite(light.power_w) && light.power_w > 0.0,
                "light power " + format_shortest(light.power_w) + " W is invalid; expected > 0");
        require(std::isfinite(light.irradiance_w_m2) && light.irradiance_w_m2 > 0.0,
                "light irradiance " + format_shortest(light.irradiance_w_m2) + " W/m^2 is invalid; expected > 0");
        if (light.spectrum == LightSpectrum::Blackbody)
            require(
                std::isfinite(light.temperature_k) && light.temperature_k >= 500.0 && light.temperature_k <= 50000.0,
                "blackbody temperature " + format_shortest(light.temperature_k) +
                    " K is out of range; expected 500 to 50000");
        if (plane && light.kind == LightKind::Directional) {
            const Vec3 d = normalised(light.vector);
            require(d[0] * d[0] + d[1] * d[1] < 1.0,
                    what + vec_text(light.vector) + " grazes the plane; expected z > 0");
        }
    }
    require(!options.lambdas_um.empty() && options.lambdas_um.size() <= std::size_t(k_max_spectral_samples),
            std::to_string(options.lambdas_um.size()) + " wavelengths; expected 1 to " +
                std::to_string(k_max_spectral_samples));
    for (double l : options.lambdas_um) validate_lambda(l);
    validate_prune_tolerance(options.prune_tolerance);
    require(std::isfinite(options.sigma_p_um) && options.sigma_p_um >= 0.0,
            "sigma_p " + format_shortest(options.sigma_p_um) + " um is invalid; expected > 0 (0: the pixel's size)");
    for (double b : options.background)
        require(std::isfinite(b), "background " + format_shortest(b) + " is not finite");

    PreparedImage out;
    out.options = options;
    // Every pixel's footprint and directions, before any work: a footprint too large for the
    // tile or a light below a pixel's horizon is refused here.
    const CameraFrame frame = camera_frame(options);
    double lo = std::numeric_limits<double>::infinity(), hi = 0.0;
    for (int r = 0; r < cam.rows; ++r)
        for (int c = 0; c < cam.cols; ++c) {
            const PixelGeometry g = pixel_geometry(frame, options, r, c);
            if (!g.hit) continue;
            ++out.pixels_on_sample;
            lo = std::min(lo, g.sigma_p_um);
            hi = std::max(hi, g.sigma_p_um);
        }
    if (out.pixels_on_sample > 0) {
        out.sigma_p_min_um = lo;
        out.sigma_p_max_um = hi;
        Query q;
        q.sigma_p_um = hi;
        q.x_um = q.y_um = 0.0;
        try {
            validate(q);
            Query ql = q;
            ql.sigma_p_um = lo;
            validate(ql);
            validate_footprint(hi, heightfield.period_x_um(), heightfield.period_y_um());
        } catch (const std::domain_error& e) {
            throw std::domain_error(std::string("pixel footprint: ") + e.what() +
                                    (options.sigma_p_um > 0.0
                                         ? ""
                                         : " (sigma_p from the pixel's size; give --sigma-p-um or move the camera)"));
        }
    }
    // Memory: the image (RGB double while rendering, float result), the evaluator's tables
    // (heightfield copy, heights and slopes: 4 doubles per texel), per-thread row buffers and
    // footprint kernel lists (≈ 10 doubles per kernel within 3σ_p).
    const double pixels = double(cam.rows) * double(cam.cols);
    const double texels = double(heightfield.rows()) * double(heightfield.cols());
    const double image_bytes = pixels * 3.0 * (sizeof(double) + sizeof(float));
    const double table_bytes = texels * 4.0 * sizeof(double);
    const double kernels = std::min(texels,
                                    k_pi * std::pow(3.0 * std::max(hi, 0.0) / heightfield.texel_um() + 1.0, 2.0));
    const double thread_bytes = double(omp_get_max_threads()) *
                                (kernels * 12.0 * sizeof(double) +
                                 double(cam.cols) * (double(options.lambdas_um.size()) + 8.0) * sizeof(double));
    out.estimated_bytes = image_bytes + table_bytes + thread_bytes;
    out.memory_note = "memory: about " + format_bytes(out.estimated_bytes) + " (image " + format_bytes(image_bytes) +
                      ", heightfield tables " + format_bytes(table_bytes) + ")";
    require_memory(out.estimated_bytes, memory_limit(options.max_memory_gb), "the image");
    return out;
}

namespace {

// What the forward pass and the gradient share: the evaluator, the mix, the light spectra, and
// per row and light the samples of the lit pixels with their weight cos θ_i E_⊥.
struct ImageWalker {
    ImageWalker(const Heightfield& heightfield, const PreparedImage& prepared)
        : options(prepared.options),
          frame(camera_frame(options)),
          eval(heightfield, options.lambdas_um, {options.model, options.prune_tolerance, options.single_precision}),
          L(options.lambdas_um.size()),
          mix(spectral_mix_weights(options.lambdas_um)) {
        for (std::size_t li = 0; li < options.lights.size(); ++li) {
            const ImageLight& light = options.lights[li];
            spectra.push_back(light_spectrum(light, options.lambdas_um));
            if (light.kind != LightKind::Disc) {
                const double scale = light.kind == LightKind::Point ? light.power_w : light.irradiance_w_m2;
                emitters.push_back({light.kind, light.vector, scale, {}, li});
                continue;
            }
            std::vector<Vec3> nodes;
            std::vector<double> area;
            disc_light_nodes(light, nodes, area);
            const double disc_area = k_pi * light.radius_um * light.radius_um;
            for (std::size_t q = 0; q < nodes.size(); ++q)
                emitters.push_back(
                    {LightKind::Disc, nodes[q], light.power_w * (area[q] / disc_area) / k_pi, disc_normal(light), li});
        }
    }

    // Row r's geometry, then visit(light) per emitter with its lit samples, their columns and weights.
    template <typename Visit>
    void row(int r, std::vector<PixelGeometry>& geometry, Visit&& visit) {
        const int cols = frame.cols;
        geometry.resize(static_cast<std::size_t>(cols));
        for (int c = 0; c < cols; ++c) geometry[std::size_t(c)] = pixel_geometry(frame, options, r, c);
        for (const Emitter& emitter : emitters) {
            samples.clear();
            column.clear();
            weight.clear();
            for (int c = 0; c < cols; ++c) {
                const PixelGeometry& g = geometry[std::size_t(c)];
                if (!g.hit) continue;
                Vec3 omega;
                double irradiance;
                light_at(emitter, g.point, omega, irradiance);
                // Below this point's horizon: on the plane and on a convex sample that is exactly
                // the shadow.
                const double cos_i = dot(omega, g.n);
                if (!(cos_i > 0.0) || !(irradiance > 0.0)) continue;  // or the point is behind a disc
                PointSample s;
                s.x_um = g.x_um;
                s.y_um = g.y_um;
                s.sigma_p_um = g.sigma_p_um;
                s.omega_i = {dot(omega, g.tx), dot(omega, g.ty)};
                s.omega_o = g.omega_o;
                if (s.omega_i[0] * s.omega_i[0] + s.omega_i[1] * s.omega_i[1] >= 1.0) continue;
                samples.push_back(s);
                column.push_back(c);
                weight.push_back(cos_i * irradiance);
            }
            visit(emitter.light);
        }
    }

    const ImageOptions& options;
    CameraFrame frame;
    PointEvaluator eval;
    std::size_t L;
    std::vector<double> mix;
    std::vector<std::vector<double>> spectra;
    std::vector<Emitter> emitters;  // the lights, a disc light as its quadrature's nodes
    std::vector<PointSample> samples;
    std::vector<int> column;
    std::vector<double> weight;  // cos θ_i E_⊥ per sample
};

}  // namespace

std::vector<double> render_image_values(const Heightfield& heightfield, const PreparedImage& prepared,
                                        const ImageProgress& progress) {
    ImageWalker walk(heightfield, prepared);
    const ImageOptions& options = prepared.options;
    const int rows = walk.frame.rows, cols = walk.frame.cols;
    const std::size_t L = walk.L;
    std::vector<double> image;
    allocating("the " + std::to_string(rows) + "x" + std::to_string(cols) + " image",
               double(rows) * cols * 3 * sizeof(double), [&] { image.assign(std::size_t(rows) * cols * 3, 0.0); });
    std::vector<PixelGeometry> geometry;
    std::vector<double> values;
    for (int r = 0; r < rows; ++r) {
        check_interrupt();
        double* rgb = image.data() + std::size_t(r) * std::size_t(cols) * 3;
        walk.row(r, geometry, [&](std::size_t li) {
            values.resize(walk.samples.size() * L);
            walk.eval.evaluate(walk.samples.data(), walk.samples.size(), values.data());
            for (std::size_t s = 0; s < walk.samples.size(); ++s)
                for (std::size_t l = 0; l < L; ++l) {
                    const double f = values[s * L + l] * walk.spectra[li][l] * walk.weight[s];
                    for (std::size_t ch = 0; ch < 3; ++ch)
                        rgb[std::size_t(walk.column[s]) * 3 + ch] += walk.mix[ch * L + l] * f;
                }
        });
        for (int c = 0; c < cols; ++c)
            if (!geometry[std::size_t(c)].hit)
                for (std::size_t ch = 0; ch < 3; ++ch) rgb[std::size_t(c) * 3 + ch] = options.background[ch];
        if (progress && !progress(r + 1, rows)) throw Interrupted();
    }
    return image;
}

RgbImage render_image(const Heightfield& heightfield, const PreparedImage& prepared, const ImageProgress& progress) {
    const std::vector<double> values = render_image_values(heightfield, prepared, progress);
    RgbImage image;
    image.rows = prepared.options.camera.rows;
    image.cols = prepared.options.camera.cols;
    image.data.resize(values.size());
    for (std::size_t k = 0; k < values.size(); ++k) image.data[k] = static_cast<float>(values[k]);
    return image;
}

void image_gradient(const Heightfield& heightfield, const PreparedImage& prepared, const std::vector<double>& dL_dimage,
                    std::vector<double>& gradient) {
    ImageWalker walk(heightfield, prepared);
    const int rows = walk.frame.rows, cols = walk.frame.cols;
    const std::size_t pixels = std::size_t(rows) * std::size_t(cols);
    if (dL_dimage.size() != pixels * 3)
        throw std::invalid_argument("image gradient weights have " + std::to_string(dL_dimage.size()) +
                                    " values; expected rows*cols*3 = " + std::to_string(pixels * 3));
    const std::size_t texels = std::size_t(heightfield.rows()) * std::size_t(heightfield.cols());
    if (gradient.empty()) gradient.assign(texels, 0.0);
    if (gradient.size() != texels)
        throw std::invalid_argument("gradient has " + std::to_string(gradient.size()) +
                                    " values; expected rows*cols = " + std::to_string(texels));
    const std::size_t L = walk.L;
    std::vector<PixelGeometry> geometry;
    std::vector<double> weights;
    for (int r = 0; r < rows; ++r) {
        check_interrupt();
        const double* d = dL_dimage.data() + std::size_t(r) * std::size_t(cols) * 3;
        walk.row(r, geometry, [&](std::size_t li) {
            // The image is linear in every f: ∂L/∂f_{s,l} = Σ_c dL/dI_c · M[c, l] · S_l · cos θ_i E.
            weights.assign(walk.samples.size() * L, 0.0);
            for (std::size_t s = 0; s < walk.samples.size(); ++s)
                for (std::size_t l = 0; l < L; ++l) {
                    double w = 0.0;
                    for (std::size_t ch = 0; ch < 3; ++ch)
                        w += d[std::size_t(walk.column[s]) * 3 + ch] * walk.mix[ch * L + l];
                    weights[s * L + l] = w * walk.spectra[li][l] * walk.weight[s];
                }
            walk.eval.adjoint(walk.samples.data(), walk.samples.size(), weights.data(), gradient);
        });
    }
}

void write_image_exr(const std::string& path, const RgbImage& image, const std::string& made_by) {
    if (image.rows < 1 || image.cols < 1 || image.data.size() != std::size_t(image.rows) * image.cols * 3)
        throw std::invalid_argument("image to write is empty or its data does not hold rows*cols*3 values");
    write_file_atomically(path, [&](const std::string& file) {
        Imf::Header header(image.cols, image.rows);
        const char* names[3] = {"R", "G", "B"};
        for (const char* name : names) header.channels().insert(name, Imf::Channel(Imf::FLOAT));
        header.insert("wavebrdf:unit", Imf::StringAttribute(k_image_unit));
        header.insert("wavebrdf:made_by", Imf::StringAttribute(made_by.substr(0, k_max_attribute_chars)));
        header.insert("wavebrdf:version", Imf::StringAttribute(k_version));
        Imf::FrameBuffer frame;
        const std::size_t stride = 3 * sizeof(float);
        for (int c = 0; c < 3; ++c)
            frame.insert(names[c],
                         Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(const_cast<float*>(image.data.data() + c)),
                                    stride, stride * std::size_t(image.cols)));
        Imf::OutputFile out(file.c_str(), header);
        out.setFrameBuffer(frame);
        out.writePixels(image.rows);
    });
}

std::vector<double> image_luminance(const RgbImage& image) {
    std::vector<double> luminance(std::size_t(image.rows) * std::size_t(image.cols));
    for (std::size_t p = 0; p < luminance.size(); ++p)
        luminance[p] = 0.2126 * double(image.data[3 * p]) + 0.7152 * double(image.data[3 * p + 1]) +
                       0.0722 * double(image.data[3 * p + 2]);
    return luminance;
}

void write_image_png(const std::string& path, const RgbImage& image, double exposure_stops, bool automatic) {
    double exposure = exposure_stops;
    if (automatic) exposure += auto_exposure(image_luminance(image));
    write_rgb_png(path, image, exposure, true);
}

}  // namespace wavebrdf
