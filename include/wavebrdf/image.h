#pragma once
// Camera images of a heightfield (docs/image.md): a camera looks at a sample carrying the
// heightfield, lights shine on it, and every pixel is the wave-optical BRDF of its own footprint
// (point_eval.h) — the patch where the pixel's ray meets the surface, σ_p from the pixel's
// projected size — at its own pair of directions, weighted into radiance.
//
// The scene frame: positions in µm; z is the plane's normal, x and y are the heightfield's rows
// and columns (docs/model.md §6); the plane sample is centred at the origin.
//
// A pixel's value: L = Σ_lights Σ_λ M(λ) S(λ) f_r(ω_i, ω_o, λ) cos θ_i E_⊥, in W/(m² sr) as
// linear sRGB (D65), with M the spectral mix of the slices (spectrum.h), S the light's relative
// spectrum (mean 1 over the samples) and E_⊥ the light's irradiance on a surface facing it
// (point light: power / (4π d²), d in metres; directional: its irradiance). One wavelength: R =
// G = B. Pixels whose ray misses the sample hold the background.
//
// The run has the shape of the other runs: typed options, validated once (prepare_image, which
// throws before any work and states the memory), then run() with a progress callback.
#include <array>
#include <cstddef>
#include <functional>
#include <string>
#include <vector>

#include "wavebrdf/heightfield.h"
#include "wavebrdf/io.h"
#include "wavebrdf/model.h"

namespace wavebrdf {

struct ImageCamera {
    std::array<double, 3> position{{0.0, 0.0, 1000.0}};  // µm, above the plane (z > 0)
    std::array<double, 3> look_at{{0.0, 0.0, 0.0}};      // µm
    // Up in the picture; the default (0, 0, 0) means +z, or −x when the camera looks along z
    // (then image rows follow +x and columns +y, as heightfield pictures show them).
    std::array<double, 3> up{{0.0, 0.0, 0.0}};
    double fov_deg = 30.0;       // pinhole: full angle across the image rows, 0 < fov < 180
    bool orthographic = false;   // parallel projection along look_at − position
    double view_width_um = 0.0;  // orthographic: width across the rows, µm; 0: the plane's
    int rows = 256, cols = 256;  // 1 … 8192 each
};

enum class LightKind { Point, Directional, Disc };

// What carries the heightfield (docs/image.md states each mapping).
enum class SampleShape {
    Plane,     // the plate of plane_size_um in the z = 0 plane
    Sphere,    // radius_um about the origin, poles on the y axis
    Cylinder,  // radius_um about the x axis, length_um along it, centred at the origin; no caps
};

// A light's relative spectrum S(λ) at the sampled wavelengths, normalised to mean 1.
enum class LightSpectrum {
    White,      // S = 1: the equal-energy white of the slices
    Blackbody,  // Planck's law at temperature_k
};

struct ImageLight {
    LightKind kind = LightKind::Point;
    // Point: position, µm (z > 0). Directional: direction from the surface towards the light
    // (any length, z > 0).
    std::array<double, 3> vector{{0.0, 0.0, 1000.0}};
    double power_w = 1.0;          // point: radiant power, W (isotropic)
    double irradiance_w_m2 = 1.0;  // directional: irradiance on a surface facing it, W/m²
    LightSpectrum spectrum = LightSpectrum::White;
    double temperature_k = 5500.0;  // blackbody: 500 … 50000 K
    // Disc: a Lambertian emitter of power_w (one-sided) centred at `vector` (µm), radius_um,
    // facing the origin; its radiance P / (π · π r²). Integrated over its area by the product
    // rule of disc_order n: n Gauss–Legendre radii × 2n equally spaced angles (2n² nodes, each a
    // point emitter with its area weight and cos θ at the disc), exact for integrands that are
    // polynomials of degree ≤ 2n − 2 in the radius and trigonometric of degree < 2n in the angle.
    double radius_um = 0.0;
    int disc_order = 4;  // 1 … 32
};

// The quadrature of a disc light: node positions (µm) and their area weights (µm², summing to
// π r²).
void disc_light_nodes(const ImageLight& light, std::vector<std::array<double, 3>>& positions,
                      std::vector<double>& weights);

struct ImageOptions {
    ImageCamera camera;
    // The plane sample: a plate of plane_size_um[0] along x by plane_size_um[1] along y, centred
    // at the origin, carrying the heightfield tiled periodically with texel (0, 0) at the corner
    // (−W/2, −H/2); rotation_deg turns the heightfield in the plane (counter-clockwise seen from
    // +z: rows then run along (cos, sin, 0)).
    std::array<double, 2> plane_size_um{{512.0, 512.0}};
    double rotation_deg = 0.0;
    // The sample's shape; a sphere or cylinder carries the heightfield through the mapping of
    // sample_surface_at (texel (0, 0) at its top point (0, 0, R), rows along +x there).
    SampleShape shape = SampleShape::Plane;
    double radius_um = 0.0;  // sphere, cylinder: 0 < R <= 1e9
    double length_um = 0.0;  // cylinder: 0 < L <= 1e9
    std::vector<ImageLight> lights;
    // Wavelengths: one (a laser, R = G = B) or several (spectral_wavelengths_um(K) for
    // `--spectral K`), µm.
    std::vector<double> lambdas_um{0.5};
    Model model = Model::OHS;
    // σ_p of every footprint, µm; 0: from the pixel's projected size, half the square root of
    // the area the pixel covers on the surface.
    double sigma_p_um = 0.0;
    double prune_tolerance = 1e-4;                      // point_eval.h's τ; 0: the full sum
    bool single_precision = false;                      // point_eval.h's: the forward sum in float (about 2x faster)
    std::array<double, 3> background{{0.0, 0.0, 0.0}};  // linear sRGB of pixels off the sample
    double max_memory_gb = 0.0;                         // refuse a run whose estimate exceeds this; 0: physical memory
};

// The run, validated and sized (nothing rendered yet).
struct PreparedImage {
    ImageOptions options;
    double estimated_bytes = 0.0;                       // peak: the image, the heightfield's tables, per-thread rows
    double sigma_p_min_um = 0.0, sigma_p_max_um = 0.0;  // over the pixels on the sample
    long long pixels_on_sample = 0;
    std::string memory_note;  // one line: "memory: about X (image Y, heightfield tables Z)"
};

// Validates everything (std::domain_error / std::invalid_argument, one line naming the value and
// what was expected): the camera (above the plane, not looking away from it, fov in (0, 180),
// look_at ≠ position), the lights (above the plane: a light behind the sample is refused), the
// wavelengths, σ_p (given, or every pixel's: at most 10 tile periods, gabor.h), the memory.
PreparedImage prepare_image(const Heightfield& heightfield, const ImageOptions& options);

// Progress: called with (rows done, rows) after each row; return false to stop (the run then
// throws wavebrdf::Interrupted).
using ImageProgress = std::function<bool(int, int)>;

// The picture: rows × cols linear sRGB (W/(m² sr)), row-major, channel-interleaved, float.
RgbImage render_image(const Heightfield& heightfield, const PreparedImage& prepared,
                      const ImageProgress& progress = {});

// The same picture in double precision (rows · cols · 3 values, row-major, interleaved): what
// render_image rounds to float, and what image_gradient differentiates.
std::vector<double> render_image_values(const Heightfield& heightfield, const PreparedImage& prepared,
                                        const ImageProgress& progress = {});

// Images are differentiable: adds Σ_{pixels, c} dL_dimage[3p + c] · ∂image[3p + c]/∂h into
// `gradient` (heightfield rows · cols, per raw height value in texel units; an empty vector is
// sized and zeroed first) — the gradient of a loss L of the image whose derivative with respect
// to the image is dL_dimage (rows · cols · 3). Pixels off the sample contribute nothing. Cost:
// about twice the forward pass (PointEvaluator::adjoint). std::invalid_argument on a size mismatch.
void image_gradient(const Heightfield& heightfield, const PreparedImage& prepared, const std::vector<double>& dL_dimage,
                    std::vector<double>& gradient);

// What the EXR's "wavebrdf:unit" attribute says.
extern const char* const k_image_unit;

// Writes the picture as a float RGB EXR with "wavebrdf:unit", "wavebrdf:made_by" and the
// version as attributes (atomically, as io.h's writers).
void write_image_exr(const std::string& path, const RgbImage& image, const std::string& made_by);

// The luminance 0.2126 R + 0.7152 G + 0.0722 B of every pixel (row-major).
std::vector<double> image_luminance(const RgbImage& image);

// The tone-mapped preview: 2^exposure_stops · value, Reinhard, sRGB curve, 8 bit. With
// auto_exposure, the exposure that maps the 99.9th percentile of the luminance to 4 is added.
void write_image_png(const std::string& path, const RgbImage& image, double exposure_stops, bool auto_exposure);

// A point of the sample's surface with its frame: heightfield coordinates (x_um, y_um), the
// point, the mapping's derivatives ∂point/∂x and ∂point/∂y, and the orthonormal right-handed frame
// the heightfield is laid in there (tangent_x along its rows, tangent_y along its columns,
// normal = tangent_x × tangent_y, pointing out of the sample). The tangent frame is the
// (unrotated) mapping's normalised derivatives turned by rotation_deg about the normal.
struct SurfacePoint {
    double x_um = 0.0, y_um = 0.0;
    std::array<double, 3> point{}, dp_dx{}, dp_dy{}, tangent_x{}, tangent_y{}, normal{};
};

// The mapping (x_um, y_um) → surface, for (a, b) the unrotated coordinates
// (x = a cos ρ + b sin ρ, y = −a sin ρ + b cos ρ, ρ = rotation_deg):
//   plane:    point = (a − W/2, b − H/2, 0)
//   sphere:   φ = a/R, β = b/R (longitude about y from +z, latitude towards +y);
//             point = R (cos β sin φ, sin β, cos β cos φ)
//   cylinder: ψ = b/R (angle about x from +z); point = (a, R sin ψ, R cos ψ)
// The sphere's mapping is isometric along its equator (β = 0) and shrinks the rows' direction by
// cos β away from it; the cylinder's is isometric everywhere. The periodic heightfield meets
// itself at the seam φ = ±π (ψ = ±π) only where 2πR is a multiple of its period.
SurfacePoint sample_surface_at(const ImageOptions& options, double x_um, double y_um);

// The ray origin + t · direction (direction unit) where it first meets the sample from outside
// (t > 0): false on a miss (and for rays starting inside a sphere or cylinder).
bool sample_ray_hit(const ImageOptions& options, const std::array<double, 3>& origin,
                    const std::array<double, 3>& direction, SurfacePoint& hit, double& t);

// Orbits for sequences: `position` turned about the z axis by `degrees` (counter-clockwise seen
// from +z).
std::array<double, 3> orbit_about_z(const std::array<double, 3>& position, double degrees);

}  // namespace wavebrdf
