// The design run (design_run.h): options, preparation, the optimisation and its metrics.
#include "wavebrdf/design_run.h"
#include "wavebrdf/constants.h"

#include <png.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <numeric>
#include <random>
#include <sstream>
#include <stdexcept>

#include "core/random.h"
#include "design/anneal.h"
#include "design/blur_term.h"
#include "design/colour_bound.h"
#include "design/continuation.h"
#include "design/mixture_bound.h"
#include "design/cone_bound.h"
#include "design/engine.h"
#include "design/evaluator.h"
#include "design/grayscale.h"
#include "design/level_step.h"
#include "design/png_input.h"
#include "design/relief.h"
#include "design/target.h"
#include "design/target_more.h"
#include "wavebrdf/design.h"
#include "wavebrdf/memory.h"
#include "wavebrdf/spectrum.h"
#include "wavebrdf/table.h"
#include "wavebrdf/text.h"
#include "wavebrdf/version.h"

namespace wavebrdf {

namespace {


using detail::Complex;
using detail::Fractions;
using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point start) {
    return std::chrono::duration<double>(Clock::now() - start).count();
}

using detail::num;  // design/target.h

// The grey values of a PNG (0 … 1), luminance for colour images, at most 1024 × 1024.
std::vector<double> read_grey_png(const std::string& path, int& rows, int& cols) {
    png_image image{};
    detail::begin_png_read(image, path, "pattern image '" + path + "'");
    if (image.width < 1 || image.height < 1 || image.width > 1024 || image.height > 1024) {
        png_image_free(&image);
        throw std::invalid_argument("pattern image '" + path + "' is " + std::to_string(image.width) + " x " +
                                    std::to_string(image.height) + "; expected 1 to 1024 pixels a side");
    }
    image.format = PNG_FORMAT_GRAY;
    std::vector<png_byte> buffer(PNG_IMAGE_SIZE(image));
    if (!png_image_finish_read(&image, nullptr, buffer.data(), 0, nullptr)) {
        const std::string message = image.message;
        png_image_free(&image);
        throw std::invalid_argument("pattern image '" + path + "' cannot be read: " + message);
    }
    rows = static_cast<int>(image.height);
    cols = static_cast<int>(image.width);
    std::vector<double> out(buffer.size());
    for (std::size_t i = 0; i < buffer.size(); ++i) out[i] = buffer[i] / 255.0;
    return out;
}

struct Region {
    double r1 = 0.1, r2 = 0.5;
};

Region parse_region(const std::string& text) {
    auto bad = [&] {
        return std::invalid_argument("--region '" + text + "' is not understood; expected annulus:R1,R2 or disk:R "
                                     "with 0 <= R1 < R2 < 1");
    };
    Region r;
    auto number = [&](const std::string& s) {
        if (s.empty()) throw bad();
        char* end = nullptr;
        const double v = std::strtod(s.c_str(), &end);
        if (end != s.c_str() + s.size() || !std::isfinite(v)) throw bad();
        return v;
    };
    if (text.rfind("annulus:", 0) == 0) {
        const std::string rest = text.substr(8);
        const auto comma = rest.find(',');
        if (comma == std::string::npos) throw bad();
        r.r1 = number(rest.substr(0, comma));
        r.r2 = number(rest.substr(comma + 1));
    } else if (text.rfind("disk:", 0) == 0) {
        r.r1 = 0.0;
        r.r2 = number(text.substr(5));
    } else {
        throw bad();
    }
    if (!(r.r1 >= 0.0 && r.r1 < r.r2 && r.r2 < 1.0)) throw bad();
    return r;
}

void require_range(double value, double lo, double hi, const std::string& name, const std::string& expected) {
    if (!(value >= lo && value <= hi))
        throw std::domain_error(name + " " + num(value) + " is out of range; expected " + expected);
}

std::vector<double> level_heights(int levels, double step_um) {
    std::vector<double> h(static_cast<std::size_t>(levels));
    for (int l = 0; l < levels; ++l) h[static_cast<std::size_t>(l)] = step_um * l;
    return h;
}

// A length in a note, to four significant digits.
std::string four_digits(double v) { return format_number(v, "%.4g"); }

// The anti-mirror's level step is a design variable where the user gave none: the loop starts
// from the rule's step (anti_mirror_step) and moves Δ with the texels (the heights' phase is
// linear in Δ: Evaluator's step gradient), within (K − 1)Δ ≤ H. Not with a blur error, whose
// term holds the levels' heights, nor on a grayscale relief.
bool step_is_free(const PreparedDesign& p) {
    const DesignOptions& o = p.options;
    return o.target.kind == DesignKind::AntiMirror && o.min_feature_um == 0.0 && o.level_step_um == 0.0 &&
           o.errors.blur_um == 0.0 && o.levels > 1;
}

std::vector<double> one_hot(const std::vector<int>& level, int levels) {
    const std::size_t n2 = level.size();
    std::vector<double> w(n2 * static_cast<std::size_t>(levels), 0.0);
    for (std::size_t t = 0; t < n2; ++t) w[static_cast<std::size_t>(level[t]) * n2 + t] = 1.0;
    return w;
}

// Direct sums of a few orders' amplitudes over the texels (the aperture's sinc in closed form):
// an evaluation of the relief independent of the FFT identity, at full size. Returns the largest
// difference in flux relative to the largest flux of the wavelength, over `per_wavelength`
// orders of each (the strongest and random others).
double spot_check(const std::vector<double>& heights, int size, const std::vector<detail::OrderSet>& sets,
                  const std::vector<std::vector<double>>& flux, int per_wavelength, std::uint64_t seed,
                  std::size_t& checked) {
    double worst_rel = 0.0;
    checked = 0;
    std::mt19937_64 rng(detail::derive_seed(seed, 0x5e7c));
    for (std::size_t w = 0; w < sets.size(); ++w) {
        const auto& s = sets[w];
        if (s.size() == 0) continue;
        std::vector<std::size_t> picks;
        picks.push_back(static_cast<std::size_t>(std::max_element(flux[w].begin(), flux[w].end()) - flux[w].begin()));
        for (int r = 1; r < per_wavelength; ++r) picks.push_back(static_cast<std::size_t>(rng() % s.size()));
        const double peak = *std::max_element(flux[w].begin(), flux[w].end());
        std::vector<double> direct(picks.size(), 0.0);
#pragma omp parallel for schedule(dynamic)
        for (std::ptrdiff_t pi = 0; pi < static_cast<std::ptrdiff_t>(picks.size()); ++pi) {
            const std::size_t o = picks[static_cast<std::size_t>(pi)];
            Complex a(0.0, 0.0);
            for (int i = 0; i < size; ++i)
                for (int j = 0; j < size; ++j) {
                    const double h = heights[static_cast<std::size_t>(i) * static_cast<std::size_t>(size) +
                                             static_cast<std::size_t>(j)];
                    a += std::polar(1.0, -s.k * h * s.q[o] -
                                             2.0 * k_pi * (static_cast<double>(s.m[o]) * i + static_cast<double>(s.n[o]) * j) /
                                                 size);
                }
            a /= static_cast<double>(size) * size;
            auto sinc = [](double x) { return x == 0.0 ? 1.0 : std::sin(k_pi * x) / (k_pi * x); };
            const double sx = sinc(static_cast<double>(s.m[o]) / size), sy = sinc(static_cast<double>(s.n[o]) / size);
            const double cos_o = s.q[o] - s.cos_i;
            direct[static_cast<std::size_t>(pi)] = sx * sx * sy * sy * std::norm(a) * cos_o / s.cos_i;
        }
        for (std::size_t pi = 0; pi < picks.size(); ++pi) {
            worst_rel = std::max(worst_rel, std::abs(direct[pi] - flux[w][picks[pi]]) / std::max(peak, 1e-300));
            ++checked;
        }
    }
    return worst_rel;
}

// The far field on a picture_size² grid of ω_o offsets in [−E, E]² about the mirror direction:
// power per unit projected solid angle, mixed to linear sRGB (one wavelength: grey).
std::vector<float> far_field_picture(const std::vector<detail::OrderSet>& sets, const Fractions& power_unused,
                                     const std::vector<std::vector<double>>& flux, const std::vector<double>& lambdas,
                                     int n, double extent) {
    (void)power_unused;
    const std::vector<double> mix = spectral_mix_weights(lambdas);
    const std::size_t W = lambdas.size();
    const double pixel_area = (2.0 * extent / n) * (2.0 * extent / n);
    std::vector<float> rgb(static_cast<std::size_t>(n) * static_cast<std::size_t>(n) * 3, 0.0f);
    for (std::size_t w = 0; w < W; ++w) {
        double total = 0.0;
        for (double f : flux[w]) total += f;
        if (!(total > 0.0)) continue;
        const auto& s = sets[w];
        for (std::size_t o = 0; o < s.size(); ++o) {
            const double u = (s.dx(o) + extent) / (2.0 * extent), v = (s.dy(o) + extent) / (2.0 * extent);
            if (u < 0.0 || u >= 1.0 || v < 0.0 || v >= 1.0) continue;
            const auto i = static_cast<std::size_t>(std::min(n - 1, static_cast<int>(u * n)));
            const auto j = static_cast<std::size_t>(std::min(n - 1, static_cast<int>(v * n)));
            const double value = flux[w][o] / total / pixel_area;
            for (std::size_t c = 0; c < 3; ++c)
                rgb[(i * static_cast<std::size_t>(n) + j) * 3 + c] += static_cast<float>(mix[c * W + w] * value);
        }
    }
    return rgb;
}

// The optimal-colour limit of the target's chromaticity on these wavelengths (colour_bound.h):
// no relief, on any levels and from any view, reflects that chromaticity into a cone with a
// larger luminous efficiency Y.
// A colour counts as reached within this chromaticity distance and above this luminous efficiency;
// below them the run surveys the other views.
constexpr double k_reached_delta_uv = 0.04, k_reached_y = 0.05;
nlohmann::json optimal_colour_bound_json(const std::vector<double>& lambdas_um, const std::array<double, 3>& linear_rgb) {
    const auto weights = detail::colour_xyz_weights(lambdas_um);
    const auto b = detail::optimal_colour_bound(weights, xyz_to_uv(linear_srgb_to_xyz(linear_rgb)), k_reached_delta_uv);
    std::vector<double> band;
    for (std::size_t l = 0; l < b.reflects.size(); ++l)
        if (b.reflects[l]) band.push_back(lambdas_um[l]);
    return {{"what", "the largest luminous efficiency Y any reflectance spectrum (0 to 1 per wavelength) has at the "
                     "target chromaticity, and within delta u'v' of it, under this white light: an upper bound for "
                     "every relief, level set and view (the optimal-colour limit)"},
            {"y_at_target", b.y_at_target},
            {"delta_uv", b.tolerance},
            {"y_within_delta_uv", b.y_within},
            {"optimal_colour_reflects_um", band}};
}

// Whether a colour target's view cone holds the mirror direction (where mixtures send light).
bool colour_view_holds_mirror(const DesignOptions& o) {
    if (!o.view) return true;
    return std::hypot((*o.view)[0] + o.omega_i[0], (*o.view)[1] + o.omega_i[1]) <= o.view_cone;
}

// The phase step between neighbouring levels in the mirror direction, per wavelength:
// ν_λ = (2π/λ) Δh (cos θ_i + cos θ_o) with θ_o = θ_i.
std::vector<double> mirror_phase_steps(const PreparedDesign& p) {
    const DesignOptions& o = p.options;
    const double light2 = o.omega_i[0] * o.omega_i[0] + o.omega_i[1] * o.omega_i[1];
    const double q = 2.0 * std::sqrt(1.0 - light2);
    const double step = o.levels > 1 ? p.levels_um[1] - p.levels_um[0] : 0.0;
    std::vector<double> nu(p.lambdas_um.size());
    for (std::size_t w = 0; w < nu.size(); ++w) nu[w] = 2.0 * k_pi / p.lambdas_um[w] * step * q;
    return nu;
}

// The colour target's single best mixture of the levels (the same search as mixture_bound_json's).
detail::BestMixture colour_best_mixture(const PreparedDesign& p) {
    const DesignOptions& o = p.options;
    return detail::best_mixture(detail::colour_xyz_weights(p.lambdas_um), mirror_phase_steps(p), o.levels,
                                xyz_to_uv(linear_srgb_to_xyz(o.target.linear_rgb)), 1e-3, k_reached_y,
                                detail::derive_seed(o.seed, 0xb0d));
}

// The mixture bound (mixture_bound.h) for a view cone that holds the mirror direction, on the
// run's levels: the largest Y at the target chromaticity of any relief made of patches of level
// mixtures, the Δu′v′ such reliefs cannot beat at Y ≥ k_reached_y, what one mixture reaches (a
// local search: fine random mixing of those shares), and the run's own cone light against the
// bound at its own chromaticity, in incident power (absolute, as the metrics count it) and as a
// share of the reflected propagating power (normalised): where the design exceeds it, its detail
// did what no mixture can, and the bound does not hold for that design.
nlohmann::json mixture_bound_json(const PreparedDesign& p, const detail::Fractions& exact, const std::vector<double>& totals) {
    const DesignOptions& o = p.options;
    const std::size_t W = p.lambdas_um.size();
    const int K = o.levels;
    const double step = K > 1 ? p.levels_um[1] - p.levels_um[0] : 0.0;
    const std::vector<double> nu = mirror_phase_steps(p);
    const auto weights = detail::colour_xyz_weights(p.lambdas_um);
    const auto target_uv = xyz_to_uv(linear_srgb_to_xyz(o.target.linear_rgb));
    const detail::MixtureBound b = detail::mixture_bound(weights, nu, K, target_uv, k_reached_y);
    const detail::BestMixture one = colour_best_mixture(p);
    auto check = [&](const std::vector<double>& spectrum) {
        std::array<double, 3> X{0.0, 0.0, 0.0};
        for (std::size_t c = 0; c < 3; ++c)
            for (std::size_t w = 0; w < W; ++w) X[c] += weights[c * W + w] * spectrum[w];
        const auto uv = xyz_to_uv(X);
        const double bound = detail::mixture_bound_y(weights, nu, K, uv);
        return nlohmann::json{{"y", X[1]}, {"uv", uv}, {"bound_y_at_its_chromaticity", bound}, {"within", X[1] <= bound + 1e-9}};
    };
    std::vector<double> normalised(W), absolute(W);
    for (std::size_t w = 0; w < W; ++w) {
        absolute[w] = exact[w][0];
        normalised[w] = totals[w] > 0.0 ? exact[w][0] / totals[w] : 0.0;
    }
    nlohmann::json j{
        {"what", "the largest luminous efficiency Y at the target chromaticity of any relief made of patches of "
                 "mixtures of these levels, each patch coarser than the view cone's resolution (the cone receives "
                 "each patch's mean phasor, |sum_l p_l exp(-i l nu)|^2 per unit incident power), an upper bound "
                 "for such reliefs only (docs/design.md)"},
        {"levels", K},
        {"level_step_um", step},
        {"phase_step_rad", nu},
        {"xyz_weights", weights},
        {"grid", b.grid},
        {"y_at_target", b.y_at_target},
        {"min_y", b.min_y},
        {"reachable_at_target", b.y_at_target >= b.min_y},
        {"delta_uv_at_min_y", std::isfinite(b.delta_uv_at_min_y) ? nlohmann::json(b.delta_uv_at_min_y) : nlohmann::json(nullptr)},
        {"uv_at_min_y", b.uv_at_min_y},
        {"one_mixture", {{"what", "the best single mixture a local search found (fine random mixing of these shares): "
                                  "reachable, not a bound"},
                         {"shares", one.shares},
                         {"y", one.y},
                         {"delta_uv", one.delta_uv},
                         {"uv", one.uv}}},
        {"design_check", {{"absolute", check(absolute)}, {"normalised", check(normalised)}}}};
    return j;
}

// The cone bound (cone_bound.h) for a colour view cone about the mirror direction under normal
// light: the largest Y, in incident power, of any relief on the run's levels at the target
// chromaticity, the radius about the target within which it proves Y < k_reached_y, and the run's
// own cone light against it at its own chromaticity, in incident power (as the metrics count it,
// and where the bound holds for every relief) and as a share of the reflected propagating power
// (which the bound does not cover).
nlohmann::json cone_bound_json(const PreparedDesign& p, const detail::Fractions& exact, const std::vector<double>& totals) {
    const DesignOptions& o = p.options;
    const std::size_t W = p.lambdas_um.size();
    const int K = o.levels;
    const double step = K > 1 ? p.levels_um[1] - p.levels_um[0] : 0.0;
    const auto weights = detail::colour_xyz_weights(p.lambdas_um);
    const auto target_uv = xyz_to_uv(linear_srgb_to_xyz(o.target.linear_rgb));
    const detail::ConeProgramme prog = detail::cone_programme(o.size, o.texel_um, o.view_cone, p.lambdas_um, step, K);
    const detail::ConeBound b = detail::cone_bound(prog, weights, target_uv, k_reached_y);
    auto check = [&](const std::vector<double>& spectrum) {
        std::array<double, 3> X{0.0, 0.0, 0.0};
        for (std::size_t c = 0; c < 3; ++c)
            for (std::size_t w = 0; w < W; ++w) X[c] += weights[c * W + w] * spectrum[w];
        const auto uv = xyz_to_uv(X);
        const double bound = detail::cone_bound_y(prog, weights, uv);
        return nlohmann::json{{"y", X[1]}, {"uv", uv}, {"bound_y_at_its_chromaticity", bound}, {"within", X[1] <= bound}};
    };
    std::vector<double> normalised(W), absolute(W);
    for (std::size_t w = 0; w < W; ++w) {
        absolute[w] = exact[w][0];
        normalised[w] = totals[w] > 0.0 ? exact[w][0] / totals[w] : 0.0;
    }
    return {{"what", "an upper bound on the luminous efficiency Y, in incident power, of the light any relief on these "
                     "levels sends into the view cone about the mirror direction under normal light, at the target "
                     "chromaticity (classes of the cone's orders as non-negative cosine polynomials in the level "
                     "phase step, Parseval at each step; a semidefinite dual, docs/design.md), the unit the metrics' "
                     "luminous_efficiency counts in; it does not cover the luminous_efficiency_share_of_reflected"},
            {"units", "incident power"},
            {"levels", K},
            {"level_step_um", step},
            {"classes", b.classes},
            {"y_at_target", b.y_at_target},
            {"min_y", b.min_y},
            {"out_of_reach_at_target", b.y_at_target < b.min_y},
            {"delta_uv_ruled_out", b.delta_uv_ruled_out},
            {"design_check", {{"absolute", check(absolute)}, {"normalised", check(normalised)}}}};
}

}  // namespace

const char* to_string(DesignKind kind) {
    switch (kind) {
        case DesignKind::AntiMirror: return "anti-mirror";
        case DesignKind::Pattern: return "pattern";
        case DesignKind::Colour: return "colour";
        case DesignKind::Iridescent: return "iridescent";
        case DesignKind::Brdf: return "brdf";
    }
    return "?";
}

DesignTarget pattern_target(int rows, int cols, std::vector<double> image) {
    if (rows < 1 || cols < 1 || rows > 1024 || cols > 1024)
        throw std::invalid_argument("pattern image " + std::to_string(rows) + " x " + std::to_string(cols) +
                                    " is out of range; expected 1 to 1024 pixels a side");
    if (image.size() != static_cast<std::size_t>(rows) * static_cast<std::size_t>(cols))
        throw std::invalid_argument("pattern image has " + std::to_string(image.size()) + " values; expected " +
                                    std::to_string(rows) + " x " + std::to_string(cols));
    for (double v : image)
        if (!(std::isfinite(v) && v >= 0.0))
            throw std::domain_error("pattern image value " + num(v) + " is not a finite intensity >= 0");
    const auto [lo, hi] = std::minmax_element(image.begin(), image.end());
    if (!(*hi > *lo)) throw std::invalid_argument("pattern image is uniform; a pattern needs at least two grey values");
    DesignTarget t;
    t.kind = DesignKind::Pattern;
    t.text = "pattern";
    t.image_rows = rows;
    t.image_cols = cols;
    t.image = std::move(image);
    return t;
}

DesignTarget parse_design_target(const std::string& text) {
    if (text == "anti-mirror") return DesignTarget{};
    if (text.rfind("pattern:", 0) == 0) {
        const std::string path = text.substr(8);
        if (path.empty()) throw std::invalid_argument("--target '" + text + "' names no image; expected pattern:IMAGE.png");
        int rows = 0, cols = 0;
        std::vector<double> image = read_grey_png(path, rows, cols);
        DesignTarget t = pattern_target(rows, cols, std::move(image));
        t.text = text;
        t.image_file = path;
        return t;
    }
    if (text.rfind("colour:", 0) == 0 || text.rfind("color:", 0) == 0) {
        const std::string c = text.substr(text.find(':') + 1);
        bool ok = c.size() == 7 && c[0] == '#';
        for (std::size_t i = 1; ok && i < 7; ++i) ok = std::isxdigit(static_cast<unsigned char>(c[i])) != 0;
        if (!ok)
            throw std::invalid_argument("--target '" + text + "': colour '" + c +
                                        "' is not an sRGB colour; expected #RRGGBB (hex digits)");
        DesignTarget t;
        t.kind = DesignKind::Colour;
        t.text = text;
        for (int k = 0; k < 3; ++k) {
            t.srgb8[static_cast<std::size_t>(k)] = std::stoi(c.substr(static_cast<std::size_t>(1 + 2 * k), 2), nullptr, 16);
            t.linear_rgb[static_cast<std::size_t>(k)] = srgb_decode(t.srgb8[static_cast<std::size_t>(k)] / 255.0);
        }
        if (t.srgb8 == std::array<int, 3>{0, 0, 0})
            throw std::invalid_argument("--target '" + text + "': black has no chromaticity; expected a colour");
        return t;
    }
    if (text.rfind("iridescent:", 0) == 0) return detail::read_iridescent_target(text, text.substr(11));
    if (text.rfind("brdf:", 0) == 0) return detail::read_brdf_target(text, text.substr(5));
    throw std::invalid_argument("--target '" + text +
                                "' is unknown; expected anti-mirror, pattern:IMAGE.png, colour:#RRGGBB, "
                                "iridescent:SPEC.json or brdf:TABLE.exr");
}

FabricationErrors parse_fabrication_errors(const std::string& text) {
    FabricationErrors e;
    if (text.empty() || text == "none") return e;
    auto bad = [&](const std::string& why) {
        return std::invalid_argument("--fabrication-error '" + text + "': " + why +
                                     "; expected scale:S%,blur:Bum (e.g. scale:5%,blur:0.3um)");
    };
    std::stringstream ss(text);
    std::string part;
    while (std::getline(ss, part, ',')) {
        const auto colon = part.find(':');
        if (colon == std::string::npos) throw bad("'" + part + "' has no ':'");
        const std::string key = part.substr(0, colon);
        std::string value = part.substr(colon + 1);
        double factor = 1.0;
        if (key == "scale" && !value.empty() && value.back() == '%') {
            value.pop_back();
            factor = 0.01;
        } else if (key == "blur" && value.size() > 2 && value.compare(value.size() - 2, 2, "um") == 0) {
            value.resize(value.size() - 2);
        }
        char* end = nullptr;
        const double v = std::strtod(value.c_str(), &end);
        if (value.empty() || end != value.c_str() + value.size() || !std::isfinite(v)) throw bad("'" + part + "' has no number");
        if (key == "scale") {
            e.scale = v * factor;
            if (!(e.scale >= 0.0 && e.scale <= 0.5)) throw bad("scale " + num(e.scale) + " outside 0 to 50%");
        } else if (key == "blur") {
            e.blur_um = v;
            if (!(v >= 0.0 && v <= 10.0)) throw bad("blur " + num(v) + " um outside 0 to 10 um");
        } else {
            throw bad("'" + key + "' is unknown");
        }
    }
    return e;
}

std::vector<double> design_wavelengths_um(const DesignOptions& o) {
    if (o.target.kind == DesignKind::Brdf && o.target.table) return o.target.table->spec.lambdas_um;
    if (o.spectral == 0) return {o.lambda_um};
    std::vector<double> l(static_cast<std::size_t>(o.spectral));
    for (int k = 0; k < o.spectral; ++k)
        l[static_cast<std::size_t>(k)] = o.band_um[0] + (k + 0.5) * (o.band_um[1] - o.band_um[0]) / o.spectral;
    return l;
}

double estimate_design_bytes(const DesignOptions& o) {
    const double period = o.size * o.texel_um;
    double orders = 0.0;
    for (double lambda : design_wavelengths_um(o)) orders += k_pi * (period / lambda) * (period / lambda) + 4.0 * period / lambda;
    orders *= static_cast<double>(detail::design_lights(o).size());
    const double n2 = static_cast<double>(o.size) * o.size;
    const int K = o.levels == 0 && o.min_feature_um != 0.0 ? detail::k_grayscale_levels : o.levels;
    const double weights = 7.0 * 8.0 * K * n2;  // θ, p, Adam's two moments, gradients, one-hot
    const int threads = 2;
    const double spectra = 16.0 * K * n2 * (2.0 + threads);
    const double blur = o.errors.blur_um > 0.0 && o.min_feature_um == 0.0 ? detail::blur_term_bytes(o.size) : 0.0;
    return 1.2 * (orders * 76.0 + weights + spectra + blur + detail::more_target_bytes(o)) + 64e6;
}

// The start relief's levels (DesignOptions::start_heights_um) into p.start_level; returns the run's
// step: the given one, or where the anti-mirror's step is free (no --level-step-um) the start's
// own, the smallest gap between its heights (heights.exr stores float32: 1e-4 of a step is slack).
double start_levels(PreparedDesign& p, double step) {
    const DesignOptions& o = p.options;
    const std::vector<double>& h = o.start_heights_um;
    const std::size_t n2 = static_cast<std::size_t>(o.size) * static_cast<std::size_t>(o.size);
    if (o.min_feature_um != 0.0)
        throw std::invalid_argument("--start is a relief on levels; a grayscale design (--min-feature-um) has none");
    if (h.size() != n2)
        throw std::invalid_argument("--start has " + std::to_string(h.size()) + " texels; expected " +
                                    std::to_string(o.size) + " x " + std::to_string(o.size) + " (--size)");
    for (double v : h)
        if (!(std::isfinite(v) && v >= 0.0 && v <= o.height_range_um * (1.0 + 1e-6)))
            throw std::domain_error("--start height " + num(v) + " um is outside 0 .. --height-range-um " +
                                    num(o.height_range_um));
    const bool free = step_is_free(p);
    if (free) {
        const double given = detail::start_step_um(h);
        if (given > 0.0) step = given;
        if (!(step * (o.levels - 1) <= o.height_range_um * (1.0 + 1e-6)))
            throw std::domain_error("--start's heights are " + num(step) + " um apart; " + std::to_string(o.levels) +
                                    " levels of that step reach " + num(step * (o.levels - 1)) +
                                    " um, expected at most --height-range-um " + num(o.height_range_um));
    }
    p.start_level.resize(n2);
    for (std::size_t t = 0; t < n2; ++t) {
        const double l = std::round(h[t] / step);
        if (!(l <= o.levels - 1 && std::abs(h[t] - l * step) <= 1e-4 * step))
            throw std::invalid_argument("--start height " + num(h[t]) + " um is not on the levels 0, " + num(step) +
                                        ", ..., " + num(step * (o.levels - 1)) + " um" +
                                        (free ? " (the step the start's heights give)" : ""));
        p.start_level[t] = static_cast<int>(l);
    }
    return step;
}

namespace {

// The most CPU the annealed stage may be estimated to take (anneal_cpu_estimate_s): its sweeps cost
// grows as the tile's size to the fourth (every texel against every order).
constexpr double k_anneal_max_cpu_s = 3600.0;

// The annealed last stage (DesignOptions::anneal_sweeps) into p: where it applies, its sweeps,
// tile and estimated CPU; refusals (std::invalid_argument naming the value) where it was asked for
// and does not apply; a note where the default does not apply to an anti-mirror on levels.
void plan_anneal(PreparedDesign& p, bool grayscale) {
    const DesignOptions& o = p.options;
    const bool given = o.anneal_sweeps.has_value();
    const int sweeps = given ? *o.anneal_sweeps : detail::k_anneal_default_sweeps;
    const std::string text = "--anneal-sweeps " + std::to_string(sweeps);
    if (given) require_range(sweeps, 0, 100000, "--anneal-sweeps", "0 to 100000 sweeps");
    if (sweeps == 0) return;
    if (o.target.kind != DesignKind::AntiMirror) {
        if (given)
            throw std::invalid_argument(text + " with --target " + o.target.text +
                                        ": annealing is the anti-mirror's last stage; expected 0 or no --anneal-sweeps");
        return;
    }
    std::string why_not;
    if (grayscale) why_not = "a grayscale relief (--min-feature-um) has no levels to anneal";
    else if (o.errors.scale > 0.0 || o.errors.blur_um > 0.0)
        why_not = "the annealed stage scores the relief as drawn, not under --fabrication-error";
    if (!why_not.empty()) {
        if (given) throw std::invalid_argument(text + ": " + why_not + "; expected 0 or no --anneal-sweeps");
        p.notes.push_back("not annealed: " + why_not);
        return;
    }
    if (!given && !o.start_heights_um.empty()) {
        p.notes.push_back("not annealed: the run starts from the given relief (--start); give --anneal-sweeps S to anneal it");
        return;
    }
    const int n = p.stages.empty() ? o.size : p.stages.front().size;
    const double tile = static_cast<double>(n) / o.size;
    const double estimate = detail::anneal_cpu_estimate_s(static_cast<double>(p.orders) * tile * tile, n, o.levels, sweeps);
    if (estimate > k_anneal_max_cpu_s) {
        const std::string what = std::to_string(sweeps) + " sweeps of the " + std::to_string(n) + "x" + std::to_string(n) +
                                 " tile would take about " + format_number(estimate, "%.0f") +
                                 " CPU-s (a sweep costs as the tile's size to the fourth), more than " +
                                 format_number(k_anneal_max_cpu_s, "%.0f");
        if (given)
            throw std::invalid_argument(text + ": " + what +
                                        "; expected fewer sweeps, a smaller first tile (--continuation auto or n1,...), or 0");
        p.notes.push_back("not annealed: " + what + "; give --anneal-sweeps S to anneal fewer sweeps");
        return;
    }
    p.anneal_sweeps = sweeps;
    p.anneal_size = n;
    p.anneal_cpu_estimate_s = estimate;
    p.notes.push_back("annealed last stage: " + std::to_string(sweeps) + " sweeps of the " + std::to_string(n) + "x" +
                      std::to_string(n) + " tile after the loop designed it, about " + format_number(estimate, "%.0f") +
                      " CPU-s (estimated)" +
                      (n < o.size ? ", then repeated to " + std::to_string(o.size) + "x" + std::to_string(o.size) +
                                        " and scored"
                                  : ""));
}

}  // namespace

PreparedDesign prepare_design(const DesignOptions& options) {
    // A grayscale design (min_feature_um > 0, levels 0) is evaluated on k_grayscale_levels levels.
    DesignOptions grey = options;
    if (options.min_feature_um != 0.0 && options.levels == 0) grey.levels = detail::k_grayscale_levels;
    const DesignOptions& o = grey;
    require_range(o.size, 2, 2048, "--size", "2 to 2048 texels");
    require_range(o.texel_um, 0.05, 100.0, "--texel-um", "0.05 to 100 um");
    require_range(o.height_range_um, 1e-3, 100.0, "--height-range-um", "0.001 to 100 um");
    if (o.min_feature_um != 0.0 && options.levels != 0)
        throw std::invalid_argument("--min-feature-um " + num(o.min_feature_um) +
                                    " asks for a grayscale relief, which contradicts --levels " +
                                    std::to_string(o.levels) + " (multi-step lithography); give one of them");
    require_range(o.levels, 2, 256, "--levels", "2 to 256");
    const bool grayscale = o.min_feature_um != 0.0;
    if (grayscale) {
        require_range(o.min_feature_um, 2.0 * o.texel_um, o.size * o.texel_um, "--min-feature-um",
                      "2 x --texel-um to the tile's period (" + num(2.0 * o.texel_um) + " to " +
                          num(o.size * o.texel_um) + " um)");
        if (o.level_step_um != 0.0)
            throw std::invalid_argument("--level-step-um " + num(o.level_step_um) + " has no levels to space in a grayscale design");
    }
    require_range(o.iterations, 0, 100000, "--iterations", "0 to 100000");
    require_range(o.refine_passes, 0, 100000, "--refine-passes", "0 to 100000");
    if (o.spectral != 0) {
        require_range(o.spectral, 1, k_max_spectral_samples, "--spectral", "1 to 256 wavelengths");
        if (!(o.band_um[0] >= 0.05 && o.band_um[0] < o.band_um[1] && o.band_um[1] <= 100.0))
            throw std::domain_error("--band-um " + num(o.band_um[0]) + "," + num(o.band_um[1]) +
                                    " is not a band; expected A,B with 0.05 <= A < B <= 100 um");
    } else {
        require_range(o.lambda_um, 0.05, 100.0, "--lambda-um", "0.05 to 100 um");
    }
    const double light = std::hypot(o.omega_i[0], o.omega_i[1]);
    if (!(light < 1.0))
        throw std::domain_error("light direction (" + num(o.omega_i[0]) + ", " + num(o.omega_i[1]) +
                                ") is outside the unit disk; expected |omega_i| < 1");
    const std::array<double, 2> mirror{-o.omega_i[0], -o.omega_i[1]};
    const double mirror_r = std::hypot(mirror[0], mirror[1]);

    PreparedDesign p;
    p.options = o;
    p.lambdas_um = design_wavelengths_um(o);
    double step = o.height_range_um / (o.levels - 1);
    std::string rule_note;  // said where no step survey replaces the rule's step
    if (o.level_step_um > 0.0) {
        if (!(o.level_step_um * (o.levels - 1) <= o.height_range_um * (1.0 + 1e-12)))
            throw std::domain_error("--level-step-um " + num(o.level_step_um) + " puts the top level at " +
                                    num(o.level_step_um * (o.levels - 1)) + " um; expected at most --height-range-um " +
                                    num(o.height_range_um));
        step = o.level_step_um;
    } else if (o.target.kind == DesignKind::AntiMirror && !grayscale) {
        step = detail::anti_mirror_step(o.height_range_um, o.levels, p.lambdas_um, std::sqrt(1.0 - light * light));
        if (step < o.height_range_um / (o.levels - 1))
            rule_note = "level step " + four_digits(step) + " um (top level " + four_digits(step * (o.levels - 1)) +
                        " um): on the full range's step no design keeps the mirror order dark at every wavelength of the band" +
                        (step_is_free(p) ? "; the design starts there and moves it" : "");
    }
    if (!o.start_heights_um.empty()) step = start_levels(p, step);
    p.levels_um = level_heights(o.levels, step);
    switch (o.target.kind) {
        case DesignKind::AntiMirror: {
            const Region region = parse_region(o.region);
            require_range(o.specular_cone, 1e-4, 0.5, "--specular-cone", "1e-4 to 0.5");
            require_range(o.cone_limit, 1e-6, 1.0, "--cone-limit", "1e-6 to 1 (a fraction of the reflected power)");
            // 16 bins' std/mean is at most sqrt(15) (all the light in one bin).
            require_range(o.uniformity_limit, 1e-3, 3.87, "--uniformity-limit", "1e-3 to 3.87 (std/mean of 16 bins)");
            if (!(mirror_r + region.r2 < 1.0))
                throw std::domain_error("--region " + o.region + " about the mirror direction reaches |omega_o| = " +
                                        num(mirror_r + region.r2) + "; expected the region inside the visible disk (< 1)");
            p.target = detail::make_anti_mirror({o.specular_cone, region.r1, region.r2, o.cone_limit, o.uniformity_limit});
            break;
        }
        case DesignKind::Pattern: {
            require_range(o.window, 1e-3, 1.0, "--window", "1e-3 to 1");
            const double corner = std::hypot(std::abs(mirror[0]) + o.window, std::abs(mirror[1]) + o.window);
            if (!(corner < 1.0))
                throw std::domain_error("--window " + num(o.window) + " about the mirror direction reaches |omega_o| = " +
                                        num(corner) + "; expected the window inside the visible disk (< 1)");
            if (o.target.image_rows < 1) throw std::invalid_argument("pattern target without an image");
            p.target = detail::make_pattern({o.window, o.target.image_rows, o.target.image_cols, o.target.image});
            break;
        }
        case DesignKind::Colour: {
            require_range(o.view_cone, 1e-3, 0.5, "--view-cone", "1e-3 to 0.5");
            require_range(o.delta_uv_tolerance, 0.0, 0.1, "--delta-uv-tolerance", "0 to 0.1");
            require_range(o.delta_uv_ceiling, 0.0, 0.1, "--delta-uv-ceiling", "0 to 0.1");
            const std::array<double, 2> view = o.view ? *o.view : mirror;
            if (!(std::hypot(view[0], view[1]) + o.view_cone < 1.0))
                throw std::domain_error("view (" + num(view[0]) + ", " + num(view[1]) + ") with --view-cone " +
                                        num(o.view_cone) + " reaches outside the visible disk; expected |view| + cone < 1");
            if (p.lambdas_um.size() < 3)
                throw std::invalid_argument("--target " + o.target.text +
                                            " needs white light; give --spectral N (N >= 3), not one --lambda-um");
            detail::ColourSpec spec;
            spec.view_offset = {view[0] - mirror[0], view[1] - mirror[1]};
            spec.view_cone = o.view_cone;
            spec.rgb = o.target.linear_rgb;
            spec.lambdas_um = p.lambdas_um;
            spec.delta_uv_tolerance = o.delta_uv_tolerance;
            p.target = detail::make_colour(spec);
            break;
        }
        case DesignKind::Iridescent:
        case DesignKind::Brdf: detail::prepare_more_target(p); break;
    }
    p.stages = detail::continuation_stages(o, grayscale);
    p.estimated_bytes = estimate_design_bytes(o);
    require_memory(p.estimated_bytes, memory_limit(o.max_memory_gb), "the design");
    auto sets = std::make_shared<std::vector<detail::OrderSet>>();
    for (const auto& light : detail::design_lights(p.options))
        for (double lambda : p.lambdas_um) {
            sets->push_back(detail::make_order_set(o.size, o.texel_um, light, lambda));
            p.orders += sets->back().size();
        }
    p.target->assign(*sets);
    p.order_sets = sets;
    plan_anneal(p, grayscale);
    detail::plan_step_survey(p, step_is_free(p));
    if (!rule_note.empty() && p.step_survey_um.empty()) p.notes.insert(p.notes.begin(), rule_note);
    if (o.errors.blur_um > 0.0)
        p.notes.push_back(grayscale ? "the blur error is scored, not designed for: a grayscale loop averages the height scale errors only"
                                    : "the blur error is designed for in the discrete refinement (the relaxed phase averages the height scale errors only)");
    return p;
}

namespace {
DesignResult run_design_impl(const PreparedDesign& p, const std::function<bool(const DesignStep&)>& on_step,
                             bool survey_views);

// One tile of a continuation (detail::RunOneDesign).
DesignResult run_one_tile(const PreparedDesign& one, const detail::DesignStepFn& on_step) {
    return run_design_impl(one, on_step, one.options.survey_views);
}

// Which views reach a colour: for a few view directions (offsets along x from the mirror
// direction, inside the visible disk), a small design on the same levels, texel and light. Its
// tile (the largest divisor of the run's size up to k_survey_size) repeats into the run's tile
// with the same far field, so what a view reaches here the run's tile reaches too: a reachable
// colour is proven by a relief, not estimated.
constexpr int k_survey_size = 32, k_survey_iterations = 40, k_survey_refine_passes = 10;
nlohmann::json view_survey(const PreparedDesign& p) {
    const DesignOptions& o = p.options;
    int size = 1;
    for (int d = 1; d <= std::min(o.size, k_survey_size); ++d)
        if (o.size % d == 0) size = d;
    const std::array<double, 2> mirror{-o.omega_i[0], -o.omega_i[1]};
    nlohmann::json views = nlohmann::json::array();
    nlohmann::json best;
    double best_loss = 1e300;
    if (size < 2) return {{"size", size}, {"views", views}};
    const std::array<double, 2> own = o.view ? *o.view : mirror;
    for (double offset : {0.0, 0.1, 0.2, 0.3, 0.4}) {
        DesignOptions v = o;
        v.size = size;
        v.iterations = k_survey_iterations;
        v.refine_passes = k_survey_refine_passes;
        v.errors = {};
        v.view = std::array<double, 2>{mirror[0] + offset, mirror[1]};
        if (!(std::hypot((*v.view)[0], (*v.view)[1]) + o.view_cone < 1.0)) continue;
        if (std::hypot((*v.view)[0] - own[0], (*v.view)[1] - own[1]) < 1e-9) continue;  // the run itself
        const PreparedDesign pv = prepare_design(v);
        const DesignResult r = run_design_impl(pv, {}, false);
        const nlohmann::json j = nlohmann::json::parse(r.metrics_json);
        const nlohmann::json& e = j["metrics"]["exact"];
        nlohmann::json entry{{"view", *v.view},
                             {"delta_uv", e["delta_uv"]},
                             {"luminous_efficiency", e["luminous_efficiency"]},
                             {"linear_srgb", e["linear_srgb"]},
                             {"loss", j["metrics"]["final_loss"]}};
        views.push_back(entry);
        if (j["metrics"]["final_loss"].get<double>() < best_loss) {
            best_loss = j["metrics"]["final_loss"].get<double>();
            best = entry;
        }
    }
    return {{"what", "per view: a small design on these levels, texel and light whose tile repeats into this run's "
                     "tile (same far field), so each colour listed is reachable from that view"},
            {"size", size},
            {"iterations", k_survey_iterations},
            {"refine_passes", k_survey_refine_passes},
            {"views", views},
            {"best", best}};
}
}  // namespace

DesignResult run_design(const PreparedDesign& p, const std::function<bool(const DesignStep&)>& on_step) {
    if (!p.step_survey_um.empty()) {
        // The step surveyed first; the design (its continuation and anneal too) keeps the best. The
        // step is not moved further: from the survey's best the relaxed phase's gradient, on level
        // mixtures, moves it into another peak (0.110 -> 0.131-0.139 um on the acceptance tile, whose
        // 32² designs score 10-16 points lower there: experiments/2026-12-02-antimirror-step-survey.md).
        const detail::StepSurvey survey = detail::run_step_survey(p, on_step);
        PreparedDesign q = p;
        q.step_survey_um.clear();
        q.step_survey_first_tile = false;
        q.options.level_step_um = survey.step_um;
        q.levels_um = level_heights(p.options.levels, survey.step_um);
        DesignResult r = p.step_survey_first_tile
                             ? detail::run_continued(q, on_step, run_one_tile, &survey.tile)
                             : run_design(q, on_step);
        nlohmann::json j = nlohmann::json::parse(r.metrics_json);
        j["step_survey"] = survey.json;
        j["level_step"] = {{"what", "the anti-mirror's level step, a design variable: the step survey's best "
                                    "(step_survey), kept while the design ran, (levels - 1) x step <= height_range_um"},
                           {"start_um", survey.step_um},
                           {"final_um", survey.step_um}};
        j["timings_s"]["step_survey"] = survey.json["seconds"];
        j["timings_s"]["total"] = j["timings_s"]["total"].get<double>() + survey.json["seconds"].get<double>();
        r.metrics_json = j.dump(2);
        return r;
    }
    if (!p.stages.empty() || p.anneal_sweeps > 0) return detail::run_continued(p, on_step, run_one_tile);
    return run_design_impl(p, on_step, p.options.survey_views);
}

long long design_step_count(const PreparedDesign& p) {
    const DesignOptions& o = p.options;
    const long long budget = o.iterations + o.refine_passes;
    // The survey: one loop at the run's budget on each step.
    long long steps = static_cast<long long>(p.step_survey_um.size()) * budget;
    if (p.anneal_sweeps > 0) {
        // The loop designs the first tile alone (unless the survey did), then the sweeps; the run's
        // tile is scored, not designed.
        if (!p.step_survey_first_tile)
            steps += p.stages.empty() ? budget : p.stages.front().iterations + p.stages.front().refine_passes;
        return steps + p.anneal_sweeps;
    }
    steps += budget;
    for (std::size_t k = p.step_survey_first_tile ? 1 : 0; k < p.stages.size(); ++k)
        steps += p.stages[k].iterations + p.stages[k].refine_passes;
    return steps;
}

namespace {

// The relaxed phase's outcome: each texel's level (quantised), the target's fractions where the
// relaxation ended, and its time.
struct RelaxedLevels {
    std::vector<int> level;
    std::vector<double> latent;  // a grayscale relief's parameters z (grayscale.h); empty on levels
    Fractions fractions;
    double seconds = 0.0;
    int multiplier_updates = 0;
};

// A constrained target's blocks (target.h): the relaxed phase moves its multipliers every
// k_relaxed_block iterations, the discrete refinement runs in blocks of k_refine_block passes with a
// move between them, and a relief that still breaks a limit gets up to k_repair_blocks more blocks
// of refinement, each with ρ doubled and the multipliers moved first. Fixed lengths, not a fixed
// count: a longer schedule must not leave the multipliers still for longer (at 1000 relaxed
// iterations in ten blocks the mixture's cone grew to 4 % within one block late in the phase and
// the relief ended over both limits).
constexpr int k_relaxed_block = 20, k_refine_block = 15, k_repair_blocks = 4;

// Adam on ln Δ (the step's scale, not its size, is what the band sees), Δ kept ≤ H/(K − 1).
struct StepAdam {
    double rate = 0.0, max_um = 0.0, m1 = 0.0, m2 = 0.0;
    int t = 0;
    void update(detail::Evaluator& evaluator, double step_gradient) {
        constexpr double b1 = 0.9, b2 = 0.999;
        const double g = step_gradient * evaluator.step_um();  // ∂L/∂ln Δ
        ++t;
        m1 = b1 * m1 + (1.0 - b1) * g;
        m2 = b2 * m2 + (1.0 - b2) * g * g;
        const double c1 = 1.0 - std::pow(b1, t), c2 = 1.0 - std::pow(b2, t);
        const double ln = std::log(evaluator.step_um()) - rate * (m1 / c1) / (std::sqrt(m2 / c2) + 1e-12);
        evaluator.set_step_um(std::min(max_um, std::exp(ln)));
    }
};
// Measured (64², four seeds, 0.40–0.70 µm): rates 1e-3, 3e-3 and 1e-2 all end on 0.167–0.169 µm
// from the rule's 0.153, the region within 0.3 point of each other.
constexpr double k_step_rate = 3e-3;

// Relaxed phase: softmax over the levels per texel, p = softmax(θ / τ), τ annealed from
// k_tau_start to k_tau_end, Adam on θ; then each texel's most likely level. A grayscale run
// relaxes the heights instead (grayscale_design), warm from `warm_latent` where given.
RelaxedLevels relaxed_levels(const PreparedDesign& p, detail::Evaluator& evaluator,
                             const std::function<void(const DesignStep&)>& report, const bool& stopped,
                             const std::vector<int>* warm = nullptr, int iteration0 = 0,
                             const std::vector<double>* warm_latent = nullptr) {
    const DesignOptions& o = p.options;
    const int K = o.levels, N = o.size;
    const std::size_t n2 = static_cast<std::size_t>(N) * static_cast<std::size_t>(N);
    const bool grayscale = o.min_feature_um != 0.0;  // the relaxed phase is grayscale_design's
    const std::size_t total = grayscale ? 0 : n2 * static_cast<std::size_t>(K);
    RelaxedLevels out;
    std::mt19937_64 rng(detail::derive_seed(o.seed, 0xde5190));
    std::vector<double> theta(total);
    detail::fill_standard_normal(theta.data(), theta.size(), rng);
    if (!warm && !p.start_level.empty() && !grayscale) warm = &p.start_level;
    if (warm && !grayscale) {
        // A warm start from a relief: each texel's own level holds half the weight at τ = 1,
        // the other levels share the rest, so the mixture's far field starts near the relief's.
        const double own = std::log(0.5), other = std::log(0.5 / std::max(1, K - 1));
        for (int l = 0; l < K; ++l)
            for (std::size_t t = 0; t < n2; ++t)
                theta[static_cast<std::size_t>(l) * n2 + t] = (*warm)[t] == l ? own : other;
    } else if (o.target.kind == DesignKind::AntiMirror && !grayscale) {
        // Start from the shares of the levels that darken the mirror order over the band
        // (dark_mirror_shares, on the run's step); the loop shapes the rest.
        const double light = std::hypot(o.omega_i[0], o.omega_i[1]);
        const detail::MirrorShares start =
            detail::dark_mirror_shares(p.levels_um[1] - p.levels_um[0], K, p.lambdas_um, std::sqrt(1.0 - light * light));
        for (int l = 0; l < K; ++l) {
            const double log_share = std::log(std::max(start.shares[static_cast<std::size_t>(l)], 1e-6));
            for (std::size_t t = 0; t < n2; ++t) theta[static_cast<std::size_t>(l) * n2 + t] += log_share;
        }
    }
    std::vector<double> weights(total), grad, m1(total, 0.0), m2(total, 0.0);
    constexpr double k_tau_start = 1.0, k_tau_end = 0.05, k_rate = 0.1, k_b1 = 0.9, k_b2 = 0.999;
    auto softmax = [&](double tau) {
        for (std::size_t t = 0; t < n2; ++t) {
            double mx = -1e300;
            for (int l = 0; l < K; ++l) mx = std::max(mx, theta[static_cast<std::size_t>(l) * n2 + t]);
            double s = 0.0;
            for (int l = 0; l < K; ++l) {
                const double e = std::exp((theta[static_cast<std::size_t>(l) * n2 + t] - mx) / tau);
                weights[static_cast<std::size_t>(l) * n2 + t] = e;
                s += e;
            }
            for (int l = 0; l < K; ++l) weights[static_cast<std::size_t>(l) * n2 + t] /= s;
        }
    };
    const auto relaxed_start = Clock::now();
    int updates = 0;
    const bool free_step = step_is_free(p);
    StepAdam step_adam;
    step_adam.rate = k_step_rate;
    step_adam.max_um = o.height_range_um / (K - 1);
    double step_gradient = 0.0;
    for (int it = 0; !grayscale && it < o.iterations && !stopped; ++it) {
        const double frac = o.iterations > 1 ? static_cast<double>(it) / (o.iterations - 1) : 1.0;
        const double tau = k_tau_start * std::pow(k_tau_end / k_tau_start, frac);
        softmax(tau);
        const double loss = evaluator.evaluate(weights, &grad, &out.fractions, free_step ? &step_gradient : nullptr);
        if (free_step) step_adam.update(evaluator, step_gradient);
        // A constrained target's multipliers move at the end of each block, from the fractions
        // the block ended on; the next block optimises against them.
        if (p.target->constrained() && (it + 1) % k_relaxed_block == 0) {
            p.target->update_multipliers(out.fractions);
            ++updates;
        }
        // Through the softmax: ∂L/∂θ_ℓ = p_ℓ (g_ℓ − Σ_j p_j g_j) / τ; then Adam.
        const double c1 = 1.0 - std::pow(k_b1, it + 1), c2 = 1.0 - std::pow(k_b2, it + 1);
        for (std::size_t t = 0; t < n2; ++t) {
            double pg = 0.0;
            for (int l = 0; l < K; ++l) pg += weights[static_cast<std::size_t>(l) * n2 + t] * grad[static_cast<std::size_t>(l) * n2 + t];
            for (int l = 0; l < K; ++l) {
                const std::size_t i = static_cast<std::size_t>(l) * n2 + t;
                const double g = weights[i] * (grad[i] - pg) / tau;
                m1[i] = k_b1 * m1[i] + (1.0 - k_b1) * g;
                m2[i] = k_b2 * m2[i] + (1.0 - k_b2) * g * g;
                theta[i] -= k_rate * (m1[i] / c1) / (std::sqrt(m2[i] / c2) + 1e-12);
            }
        }
        report({"relaxed", iteration0 + it, loss, tau});
    }
    if (grayscale) {
        out.level = detail::grayscale_design(p, evaluator, report, stopped, out.fractions, out.latent, warm_latent,
                                             iteration0);
        out.seconds = seconds_since(relaxed_start);
        return out;
    }
    out.seconds = seconds_since(relaxed_start);
    out.multiplier_updates = updates;
    // Quantise: each texel's most likely level.
    out.level.resize(n2);
    for (std::size_t t = 0; t < n2; ++t) {
        int best = 0;
        for (int l = 1; l < K; ++l)
            if (theta[static_cast<std::size_t>(l) * n2 + t] > theta[static_cast<std::size_t>(best) * n2 + t]) best = l;
        out.level[t] = best;
    }
    return out;
}

// The discrete refinement's loss of a relief on the levels: the loop's model (mean over the
// height scales) and, with a blur error, the blurred relief (blur_term.h) as one more sample;
// the relaxed phase's level mixtures have no heights to blur.
class RefineLoss {
public:
    RefineLoss(const PreparedDesign& p, detail::Evaluator& evaluator, std::size_t scale_samples)
        : m_p(p), m_evaluator(evaluator), m_blur_weight(1.0 / (static_cast<double>(scale_samples) + 1.0)) {
        const DesignOptions& o = p.options;
        if (o.errors.blur_um > 0.0 && o.min_feature_um == 0.0)
            m_blur = std::make_unique<detail::BlurTerm>(p, o.errors.blur_um / o.texel_um);
    }

    double operator()(const std::vector<int>& lv, std::vector<double>* g) {
        const int K = m_p.options.levels;
        const std::size_t n2 = lv.size();
        const double nominal = m_evaluator.evaluate(one_hot(lv, K), g);
        if (!m_blur) return nominal;
        std::vector<double> gh;
        const double blurred = m_blur->evaluate(lv, g ? &gh : nullptr);
        if (g) {
            // A texel's switch from level a to b changes its height by h_b − h_a: the blurred
            // loss's gradient per level is ∂L/∂h · h_ℓ.
            for (double& x : *g) x *= 1.0 - m_blur_weight;
            for (int l = 0; l < K; ++l)
                for (std::size_t t = 0; t < n2; ++t)
                    (*g)[static_cast<std::size_t>(l) * n2 + t] += m_blur_weight * gh[t] * m_p.levels_um[static_cast<std::size_t>(l)];
        }
        return (1.0 - m_blur_weight) * nominal + m_blur_weight * blurred;
    }

private:
    const PreparedDesign& m_p;
    detail::Evaluator& m_evaluator;
    std::unique_ptr<detail::BlurTerm> m_blur;
    double m_blur_weight;
};

// Discrete passes on the levels that switch the texels the gradient predicts to gain most, kept
// only when the exact loss falls (a grayscale relief is scored, not refined). Returns the
// final loss; `level` holds the relief.
double refine_levels(const PreparedDesign& p, RefineLoss& refine_loss, std::vector<int>& level, int passes,
                     int iteration0, const std::function<void(const DesignStep&)>& report, const bool& stopped) {
    const DesignOptions& o = p.options;
    const int K = o.levels;
    const std::size_t n2 = level.size();
    const bool grayscale = o.min_feature_um != 0.0;
    std::vector<double> grad;
    double loss = refine_loss(level, &grad);
    report({"refine", iteration0, loss, 0.0});
    double fraction = 0.01;
    std::vector<double> trial_grad;
    for (int pass = 0; !grayscale && pass < passes && !stopped; ++pass) {
        std::vector<std::pair<double, std::size_t>> gain;
        std::vector<int> best(n2, -1);
        for (std::size_t t = 0; t < n2; ++t) {
            const double current = grad[static_cast<std::size_t>(level[t]) * n2 + t];
            double d = 0.0;
            for (int l = 0; l < K; ++l) {
                const double x = grad[static_cast<std::size_t>(l) * n2 + t] - current;
                if (x < d) {
                    d = x;
                    best[t] = l;
                }
            }
            if (best[t] >= 0) gain.emplace_back(d, t);
        }
        if (gain.empty()) break;
        const std::size_t take = std::min(gain.size(), std::max<std::size_t>(1, static_cast<std::size_t>(fraction * static_cast<double>(n2))));
        std::partial_sort(gain.begin(), gain.begin() + static_cast<std::ptrdiff_t>(take), gain.end());
        std::vector<int> trial = level;
        for (std::size_t k = 0; k < take; ++k) trial[gain[k].second] = best[gain[k].second];
        const double trial_loss = refine_loss(trial, &trial_grad);
        if (trial_loss < loss) {
            level.swap(trial);
            grad.swap(trial_grad);
            loss = trial_loss;
            fraction = std::min(0.1, fraction * 1.5);
        } else {
            if (take == 1) break;
            fraction /= 4.0;
        }
        report({"refine", iteration0 + pass + 1, loss, fraction});
    }
    return loss;
}

// The discrete refinement; a constrained target's runs in blocks of k_refine_block passes with its
// multipliers moved between them at the relief's fractions (the loop's model of the relief is its
// exact scalar diffraction), then, while the relief breaks one of the user's limits, repair blocks
// (k_repair_blocks at most). Returns the final loss at the final multipliers.
struct ConstrainedRefine {
    int updates = 0, repair_blocks = 0;
};
double refine_constrained(const PreparedDesign& p, detail::Evaluator& evaluator, RefineLoss& refine_loss,
                          std::vector<int>& level, const std::function<void(const DesignStep&)>& report,
                          const bool& stopped, ConstrainedRefine& c) {
    const DesignOptions& o = p.options;
    const int iteration = o.iterations;
    if (!p.target->constrained() || o.min_feature_um != 0.0)
        return refine_levels(p, refine_loss, level, o.refine_passes, iteration, report, stopped);
    auto nominal = [&] {
        Fractions f;
        (void)evaluator.evaluate(one_hot(level, o.levels), nullptr, &f);
        return f;
    };
    const int block = k_refine_block;
    double loss = 0.0;
    int done = 0;
    do {
        const int passes = std::min(block, o.refine_passes - done);
        if (done > 0) {
            p.target->update_multipliers(nominal());
            ++c.updates;
        }
        loss = refine_levels(p, refine_loss, level, passes, iteration + done, report, stopped);
        done += passes;
    } while (done < o.refine_passes && !stopped);
    while (!stopped && o.refine_passes > 0 && c.repair_blocks < k_repair_blocks) {
        const Fractions f = nominal();
        if (p.target->broken_limits(f).empty()) break;
        p.target->stiffen();
        p.target->update_multipliers(f);
        ++c.updates;
        loss = refine_levels(p, refine_loss, level, block, iteration + done, report, stopped);
        done += block;
        ++c.repair_blocks;
    }
    return loss;
}

// Brightness for chromaticity (colour and iridescent targets, on levels or grayscale). The loss
// asks for both a chromaticity (Δu′v′ → 0) and a luminous efficiency (the hinge below Y 0.1);
// the two compete, since light into the view cone at the wavelengths that pull the chromaticity
// off the target is light the hinge wants. A colour whose brightest reflectors are dim (blue: its optimal-colour limit is a
// few times the hinge's Y at best) settles where the chromaticity term's pull, which grows with
// Δu′v′ from zero, balances the hinge's, and there the schedule ends far inside any visible
// colour difference while Y is still below what a reached colour has. Only then (the loop's Y
// below k_reached_y after the schedule) does the loop continue, in blocks: the tolerance raised
// a quarter of the way from delta_uv_tolerance to delta_uv_ceiling, the relaxed phase run again
// from the relief (warm, o.iterations) and the discrete passes after it; a block's relief is
// kept only where it lowers the loss at the block's tolerance. So the Δu′v′ given up is the
// least of those steps that reaches the brightness; at the ceiling blocks continue while one
// still lowers the loss, at most k_trade_max_blocks in all. Greedy discrete passes alone, tried
// first, stop short: the levels that move light between wavelengths change many texels at once.
// A grayscale relief (--min-feature-um) runs the same blocks: its relaxed phase warm from the
// heights' parameters z where the kept relief left them, its discrete passes none (the relief
// is scored, as after its schedule).
// A design whose schedule reaches the brightness is untouched. An iridescent target trades per
// pair: each block raises the tolerance of the pairs whose Y is still below k_reached_y, so a
// bright pair's colour is not given up for a dim one's brightness; it stops when every pair
// reaches the brightness, or when a block in which every dim pair was already at the ceiling
// does not lower the loss, or after k_trade_max_blocks.
constexpr int k_trade_steps = 4, k_trade_max_blocks = 8;
struct BrightnessTrade {
    bool considered = false;  // a colour or iridescent target with a ceiling above its tolerance
    bool per_pair = false;    // iridescent: the vectors hold one entry per pair
    int blocks = 0;
    std::vector<double> tolerance, y_before, y_after;  // per view cone (colour: one)
    double loss_after = 0.0, seconds = 0.0;
};

// The loop's Y of a relief, per view cone (colour: one; iridescent: one per pair); empty for a
// target without one (a plate's highlight entry runs as a colour design with its own target).
std::vector<double> model_luminous_efficiency(const PreparedDesign& p, detail::Evaluator& evaluator,
                                              const std::vector<int>& level) {
    Fractions f;
    (void)evaluator.evaluate(one_hot(level, p.options.levels), nullptr, &f);
    const nlohmann::json m = p.target->metrics(f);
    if (!m.contains("luminous_efficiency")) return {};
    const nlohmann::json& y = m["luminous_efficiency"];
    return y.is_array() ? y.get<std::vector<double>>() : std::vector<double>{y.get<double>()};
}

BrightnessTrade trade_for_brightness(const PreparedDesign& p, detail::Evaluator& evaluator, RefineLoss& refine_loss,
                                     std::vector<int>& level, std::vector<double>& latent, double& loss,
                                     const std::function<void(const DesignStep&)>& report, const bool& stopped) {
    const DesignOptions& o = p.options;
    BrightnessTrade t;
    const bool colour = o.target.kind == DesignKind::Colour, iridescent = o.target.kind == DesignKind::Iridescent;
    const bool grayscale = o.min_feature_um != 0.0;
    if (!(colour || iridescent) || !(o.delta_uv_ceiling > o.delta_uv_tolerance) || (o.refine_passes == 0 && !grayscale))
        return t;
    const auto start = Clock::now();
    t.y_before = t.y_after = model_luminous_efficiency(p, evaluator, level);
    if (t.y_before.empty()) return t;
    t.considered = true;
    t.per_pair = iridescent;
    t.loss_after = loss;
    const std::size_t cones = t.y_before.size();
    t.tolerance.assign(cones, o.delta_uv_tolerance);
    // The loss is the prepared target's; the tolerances go back to the user's on the way out.
    struct Restore {
        detail::Target& target;
        std::size_t cones;
        double tolerance;
        ~Restore() {
            for (std::size_t q = 0; q < cones; ++q) target.set_delta_uv_tolerance(q, tolerance);
        }
    } restore{*p.target, cones, o.delta_uv_tolerance};
    const double step = (o.delta_uv_ceiling - o.delta_uv_tolerance) / k_trade_steps;
    std::vector<int> raised(cones, 0);  // each cone's blocks so far
    auto dim = [&](std::size_t q) { return t.y_after[q] < k_reached_y; };
    auto any_dim = [&] {
        for (std::size_t q = 0; q < cones; ++q)
            if (dim(q)) return true;
        return false;
    };
    int iteration = o.iterations + o.refine_passes;
    while (any_dim() && t.blocks < k_trade_max_blocks && !stopped) {
        bool at_ceiling = true;  // every dim cone's tolerance already at the ceiling before this block
        for (std::size_t q = 0; q < cones; ++q) {
            if (!dim(q)) continue;
            at_ceiling = at_ceiling && t.tolerance[q] >= o.delta_uv_ceiling;
            t.tolerance[q] = std::min(o.delta_uv_ceiling, o.delta_uv_tolerance + step * ++raised[q]);
            p.target->set_delta_uv_tolerance(q, t.tolerance[q]);
        }
        const double before = refine_loss(level, nullptr);
        RelaxedLevels block = relaxed_levels(p, evaluator, report, stopped, &level, iteration, &latent);
        iteration += o.iterations;
        double block_loss = refine_levels(p, refine_loss, block.level, o.refine_passes, iteration, report, stopped);
        iteration += o.refine_passes;
        ++t.blocks;
        if (block_loss < before) {
            level.swap(block.level);
            latent.swap(block.latent);
            t.loss_after = block_loss;
        } else {
            t.loss_after = before;
            if (at_ceiling) break;
        }
        t.y_after = model_luminous_efficiency(p, evaluator, level);
    }
    loss = t.loss_after;
    t.seconds = seconds_since(start);
    return t;
}

nlohmann::json brightness_trade_json(const PreparedDesign& p, const BrightnessTrade& t) {
    const DesignOptions& o = p.options;
    // A colour's values are numbers; an iridescent target's, one per pair.
    auto value = [&](const std::vector<double>& v) { return t.per_pair ? nlohmann::json(v) : nlohmann::json(v.at(0)); };
    return {{"what", std::string("when the schedule ends below luminous efficiency y_floor (loop's model): blocks of the "
                                 "relaxed phase (warm from the relief, iterations) and refine_passes discrete passes, the "
                                 "delta u'v' tolerance raised by a quarter of (ceiling - delta_uv_tolerance) per block up "
                                 "to the ceiling, a block kept where it lowers the loss, while Y stays below y_floor and "
                                 "the loss still falls") +
                         (t.per_pair ? "; per pair: only the tolerances of the pairs below y_floor are raised" : "") +
                         (o.min_feature_um != 0.0 ? "; grayscale: the relaxed phase warm from the kept relief's latent "
                                                    "heights, no discrete passes"
                                                  : "")},
            {"y_floor", k_reached_y},
            {"ceiling", o.delta_uv_ceiling},
            {"max_blocks", k_trade_max_blocks},
            {"blocks", t.blocks},
            {"tolerance_used", value(t.tolerance)},
            {"model_y_before", value(t.y_before)},
            {"model_y_after", value(t.y_after)},
            {"final_loss", t.loss_after},
            {"seconds", t.seconds}};
}

// A warning per view cone still below k_reached_y under exact scalar diffraction of the relief
// after blocks of the trade ran: the Y it ended at, the tolerance the blocks reached and where
// they stopped (at the ceiling, after k_trade_max_blocks, or interrupted).
std::vector<std::string> brightness_trade_warnings(const PreparedDesign& p, const BrightnessTrade& t,
                                                   const nlohmann::json& exact) {
    std::vector<std::string> out;
    if (!t.considered || t.blocks == 0 || !exact.contains("luminous_efficiency")) return out;
    const nlohmann::json& y = exact["luminous_efficiency"];
    const std::vector<double> ys = y.is_array() ? y.get<std::vector<double>>() : std::vector<double>{y.get<double>()};
    const char* why = t.blocks >= k_trade_max_blocks ? "after the most blocks" : "before the ceiling (interrupted)";
    for (std::size_t q = 0; q < ys.size() && q < t.tolerance.size(); ++q) {
        if (!(ys[q] < k_reached_y)) continue;
        char line[400];
        std::snprintf(line, sizeof line,
                      "%s Y %.3g %% is below %.3g %% after %d block%s of the brightness trade (delta u'v' tolerance %.3g, "
                      "--delta-uv-ceiling %.3g; stopped %s)%s",
                      t.per_pair ? ("pair " + std::to_string(q + 1) + "'s").c_str() : "the colour's", 100.0 * ys[q],
                      100.0 * k_reached_y, t.blocks, t.blocks == 1 ? "" : "s", t.tolerance[q], p.options.delta_uv_ceiling,
                      t.tolerance[q] >= p.options.delta_uv_ceiling ? "at the ceiling" : why,
                      p.options.min_feature_um != 0.0 ? "; a grayscale relief" : "");
        out.emplace_back(line);
    }
    return out;
}

// The exact metrics; a target counted in incident power also gets its luminous efficiency as a
// share of the reflected propagating power (each wavelength's cone flux over that wavelength's
// total), which is what a reflectance normalised to the light the surface sends anywhere shows.
nlohmann::json exact_metrics(const detail::Target& target, const Fractions& exact, const std::vector<double>& totals) {
    nlohmann::json m = target.metrics(exact);
    if (!target.incident_power()) return m;
    Fractions share = exact;
    for (std::size_t w = 0; w < share.size(); ++w)
        for (double& x : share[w]) x = totals[w] > 0.0 ? x / totals[w] : 0.0;
    const nlohmann::json s = target.metrics(share);
    m["luminous_efficiency_units"] = "fraction of the incident white light's luminous power";
    m["luminous_efficiency_share_of_reflected"] = s["luminous_efficiency"];
    return m;
}

// The finished relief's scores: the loop's model, exact scalar diffraction of the relief (the
// heights alone, re-levelled) with a direct-sum spot check, and the fabrication errors.
struct ReliefScores {
    Fractions model, exact;
    std::vector<std::vector<double>> exact_flux;
    std::vector<double> kirchhoff_totals;
    std::size_t checked = 0;
    double spot = 0.0, model_vs_exact = 0.0;
    nlohmann::json fabrication = nlohmann::json::array();
};

ReliefScores score_relief(const PreparedDesign& p, detail::Evaluator& evaluator, const DesignResult& r) {
    const DesignOptions& o = p.options;
    const int K = o.levels, N = o.size;
    const auto& sets = *p.order_sets;
    ReliefScores s;
    (void)evaluator.evaluate(one_hot(r.level, K), nullptr, &s.model);
    const detail::LevelRelief relief = detail::to_level_relief(r.heights_um, detail::k_exact_max_levels);
    s.exact_flux = detail::level_flux(relief, N, sets, 1.0);
    s.exact = detail::group_fractions(*p.target, s.exact_flux, &s.kirchhoff_totals);
    s.spot = spot_check(r.heights_um, N, sets, s.exact_flux, N >= 512 ? 4 : 16, o.seed, s.checked);
    for (std::size_t w = 0; w < s.exact.size(); ++w)
        for (std::size_t q = 0; q < s.exact[w].size(); ++q)
            s.model_vs_exact = std::max(s.model_vs_exact, std::abs(s.exact[w][q] - s.model[w][q]));
    if (o.errors.scale > 0.0)
        for (double scale : {1.0 - o.errors.scale, 1.0 + o.errors.scale}) {
            const auto flux = detail::level_flux(relief, N, sets, scale);
            std::vector<double> totals;
            const Fractions f = detail::group_fractions(*p.target, flux, &totals);
            s.fabrication.push_back({{"error", "scale " + num(scale)}, {"metrics", exact_metrics(*p.target, f, totals)}});
        }
    if (o.errors.blur_um > 0.0) {
        const std::vector<double> blurred = detail::periodic_blur(r.heights_um, N, o.errors.blur_um / o.texel_um);
        const detail::LevelRelief b = detail::to_level_relief(blurred, detail::k_exact_max_levels);
        const auto flux = detail::level_flux(b, N, sets, 1.0);
        std::vector<double> totals;
        const Fractions f = detail::group_fractions(*p.target, flux, &totals);
        s.fabrication.push_back({{"error", "blur " + num(o.errors.blur_um) + " um"},
                                 {"quantised_to_levels", b.quantised ? detail::k_exact_max_levels : 0},
                                 {"metrics", exact_metrics(*p.target, f, totals)}});
    }
    return s;
}

// The pictures on the window grid about the mirror direction: the far field of the exact
// flux and the target (r.picture_size, r.picture_extent and both pictures set).
void draw_pictures(const PreparedDesign& p, const ReliefScores& scores, DesignResult& r) {
    const DesignOptions& o = p.options;
    const std::array<double, 2> mirror{-o.omega_i[0], -o.omega_i[1]};
    // A brdf target's pictures on its table's ω_o grid (about the mirror direction): what it is scored on.
    r.picture_size = o.target.kind == DesignKind::Brdf ? o.target.table->spec.resolution : 256;
    double extent = 0.3;
    switch (o.target.kind) {
        case DesignKind::AntiMirror: extent = std::min(1.0, 1.2 * parse_region(o.region).r2); break;
        case DesignKind::Pattern: extent = o.window; break;
        case DesignKind::Colour: {
            const std::array<double, 2> view = o.view ? *o.view : mirror;
            extent = std::min(1.0, std::max(std::abs(view[0] - mirror[0]), std::abs(view[1] - mirror[1])) + 2.0 * o.view_cone);
            break;
        }
        case DesignKind::Iridescent:
        case DesignKind::Brdf: extent = detail::more_picture_extent(o); break;
    }
    r.picture_extent = extent;
    const int n = r.picture_size;
    r.far_field_picture = far_field_picture(*p.order_sets, scores.exact, scores.exact_flux, p.lambdas_um, n, extent);
    r.target_picture.assign(static_cast<std::size_t>(n) * static_cast<std::size_t>(n) * 3, 0.0f);
    if (o.target.kind == DesignKind::Iridescent || o.target.kind == DesignKind::Brdf) {
        detail::more_target_picture(o, n, extent, r.target_picture);
        return;
    }
    const double pixel_area = (2.0 * extent / n) * (2.0 * extent / n);
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
            const double dx = (i + 0.5) / n * 2.0 * extent - extent, dy = (j + 0.5) / n * 2.0 * extent - extent;
            std::array<double, 3> c{0.0, 0.0, 0.0};
            if (o.target.kind == DesignKind::AntiMirror) {
                const Region g = parse_region(o.region);
                const double rr = std::hypot(dx, dy);
                const double area = k_pi * (g.r2 * g.r2 - g.r1 * g.r1);
                if (rr >= g.r1 && rr <= g.r2) c = {1.0 / area, 1.0 / area, 1.0 / area};
            } else if (o.target.kind == DesignKind::Pattern) {
                const int ii = std::min(o.target.image_rows - 1, static_cast<int>((i + 0.5) / n * o.target.image_rows));
                const int jj = std::min(o.target.image_cols - 1, static_cast<int>((j + 0.5) / n * o.target.image_cols));
                const double sum = std::accumulate(o.target.image.begin(), o.target.image.end(), 0.0);
                const double cell = pixel_area * n * n / (static_cast<double>(o.target.image_rows) * o.target.image_cols);
                const double v = o.target.image[static_cast<std::size_t>(ii * o.target.image_cols + jj)] / (sum * cell);
                c = {v, v, v};
            } else {
                const std::array<double, 2> view = o.view ? *o.view : mirror;
                if (std::hypot(dx - (view[0] - mirror[0]), dy - (view[1] - mirror[1])) <= o.view_cone) c = o.target.linear_rgb;
            }
            for (std::size_t k = 0; k < 3; ++k)
                r.target_picture[(static_cast<std::size_t>(i) * static_cast<std::size_t>(n) + static_cast<std::size_t>(j)) * 3 + k] =
                    static_cast<float>(c[k]);
        }
}

// design.json's "target": its kind, text and the settings that define it.
nlohmann::json target_json(const DesignOptions& o) {
    const std::array<double, 2> mirror{-o.omega_i[0], -o.omega_i[1]};
    nlohmann::json target{{"kind", to_string(o.target.kind)}, {"text", o.target.text}};
    if (o.target.kind == DesignKind::AntiMirror) {
        const Region g = parse_region(o.region);
        target["specular_cone"] = o.specular_cone;
        target["cone_limit"] = o.cone_limit;
        target["uniformity_limit"] = o.uniformity_limit;
        target["region"] = o.region;
        target["region_r1"] = g.r1;
        target["region_r2"] = g.r2;
    } else if (o.target.kind == DesignKind::Pattern) {
        target["window"] = o.window;
        target["image_rows"] = o.target.image_rows;
        target["image_cols"] = o.target.image_cols;
        target["image_file"] = o.target.image_file;
    } else if (o.target.kind == DesignKind::Colour) {
        const std::array<double, 2> view = o.view ? *o.view : mirror;
        target["srgb8"] = o.target.srgb8;
        target["linear_rgb"] = o.target.linear_rgb;
        target["view"] = view;
        target["view_cone"] = o.view_cone;
        target["delta_uv_tolerance"] = o.delta_uv_tolerance;
        target["delta_uv_ceiling"] = o.delta_uv_ceiling;
    } else {
        detail::more_target_json(o, target);
    }
    return target;
}

// A colour target's extras in design.json: the mixture bound (where the view holds the mirror
// and the levels are few enough), the cone bound (normal light, the view cone on the mirror
// direction) and, when the colour is missed, the view survey. Returns the notes of the bounds
// that were not computed.
std::vector<std::string> add_colour_reach(const PreparedDesign& p, const ReliefScores& scores, bool survey_views,
                                          nlohmann::json& j) {
    const DesignOptions& o = p.options;
    const int K = o.levels;
    const bool grayscale = o.min_feature_um != 0.0;
    std::string mixture_note, cone_note;
    // The programme grows as 8K rows by K columns and the dense simplex with it (minutes at
    // 256 levels), so it is solved up to k_mixture_bound_max_levels; a failure is a note, never
    // the end of a finished design.
    constexpr int k_mixture_bound_max_levels = 64;
    if (colour_view_holds_mirror(o) && !grayscale) {
        if (K > k_mixture_bound_max_levels) {
            mixture_note = "the mixture bound is computed for up to " + std::to_string(k_mixture_bound_max_levels) +
                           " levels; this run has " + std::to_string(o.levels);
        } else {
            try {
                j["mixture_bound"] = mixture_bound_json(p, scores.exact, scores.kirchhoff_totals);
            } catch (const std::runtime_error& e) {
                mixture_note = std::string("the mixture bound was not computed: ") + e.what();
            }
        }
    }
    // The cone bound: normal light, the view cone centred on the mirror direction, levels.
    const bool normal_light = o.omega_i[0] == 0.0 && o.omega_i[1] == 0.0;
    const bool centred = !o.view || ((*o.view)[0] == 0.0 && (*o.view)[1] == 0.0);
    if (normal_light && centred && !grayscale && K >= 2 && K <= 64) {
        try {
            j["cone_bound"] = cone_bound_json(p, scores.exact, scores.kirchhoff_totals);
        } catch (const std::exception& e) {
            cone_note = std::string("the cone bound was not computed: ") + e.what();
        }
    }
    const nlohmann::json& e = j["metrics"]["exact"];
    // Grayscale reliefs (no levels) are not surveyed.
    const bool reached = !survey_views || o.min_feature_um > 0.0 || !e.contains("delta_uv") || !e.contains("luminous_efficiency") ||
                         (e["delta_uv"].get<double>() <= k_reached_delta_uv &&
                          e["luminous_efficiency"].get<double>() >= k_reached_y);
    // A colour the cone bound rules out for this view is surveyed too: which view reaches it.
    const bool ruled_out = j.contains("cone_bound") && j["cone_bound"]["out_of_reach_at_target"].get<bool>();
    if (!reached || (survey_views && o.min_feature_um == 0.0 && ruled_out)) {
        const auto survey_start = Clock::now();
        j["view_survey"] = view_survey(p);
        j["view_survey"]["seconds"] = seconds_since(survey_start);
    }
    std::vector<std::string> notes;
    for (const std::string& note : {mixture_note, cone_note})
        if (!note.empty()) notes.push_back(note);
    return notes;
}

// design.json without its colour extras and timings.
nlohmann::json design_json(const PreparedDesign& p, const DesignResult& r, const RelaxedLevels& relaxed,
                           const ReliefScores& scores, double loss, bool stopped) {
    const DesignOptions& o = p.options;
    nlohmann::json j;
    j["kind"] = "design";
    j["version"] = k_version;
    j["target"] = target_json(o);
    j["picture_extent"] = r.picture_extent;
    j["light"] = {{"omega_i", o.omega_i}, {"lambdas_um", p.lambdas_um}, {"spectral", o.spectral},
                  {"band_um", o.spectral ? nlohmann::json(o.band_um) : nlohmann::json(nullptr)}};
    j["constraints"] = {{"size", o.size}, {"texel_um", o.texel_um}, {"height_range_um", o.height_range_um},
                        {"levels", o.levels}, {"fabrication_error", {{"scale", o.errors.scale}, {"blur_um", o.errors.blur_um}}}};
    if (o.min_feature_um != 0.0) j["constraints"]["min_feature_um"] = o.min_feature_um;
    j["levels_um"] = r.levels_um;
    j["seed"] = o.seed;
    j["options"] = {{"iterations", o.iterations}, {"refine_passes", o.refine_passes}, {"stopped_early", stopped}};
    // One tile (run_continued rewrites this for a continuation).
    j["options"]["continuation"] = o.continuation;
    j["continuation"] = {{"setting", o.continuation},
                         {"schedule", {{{"size", o.size}, {"iterations", o.iterations}, {"refine_passes", o.refine_passes}}}}};
    j["orders"] = p.orders;
    j["estimated_bytes"] = p.estimated_bytes;
    j["metrics"] = {
        {"model", p.target->metrics(scores.model)},
        {"exact", exact_metrics(*p.target, scores.exact, scores.kirchhoff_totals)},
        {"relaxed", relaxed.fractions.empty() ? nlohmann::json(nullptr) : p.target->metrics(relaxed.fractions)},
        {"model_vs_exact_max_fraction_difference", scores.model_vs_exact},
        {"exact_direct_sum_check", {{"orders", scores.checked}, {"max_flux_difference_relative_to_peak", scores.spot}}},
        {"kirchhoff_total", scores.kirchhoff_totals},
        {"final_loss", loss}};
    j["fabrication_errors"] = scores.fabrication;
    if (o.target.kind == DesignKind::Colour)
        j["optimal_colour_bound"] = optimal_colour_bound_json(p.lambdas_um, o.target.linear_rgb);
    if (o.target.kind == DesignKind::Iridescent) {
        nlohmann::json pairs = nlohmann::json::array();
        for (const auto& pair : o.target.pairs) pairs.push_back(optimal_colour_bound_json(p.lambdas_um, pair.linear_rgb));
        j["optimal_colour_bound"] = pairs;
    }
    return j;
}

DesignResult run_design_impl(const PreparedDesign& p, const std::function<bool(const DesignStep&)>& on_step,
                             bool survey_views) {
    const DesignOptions& o = p.options;
    const auto start = Clock::now();
    std::vector<double> scales{1.0};
    if (o.errors.scale > 0.0) scales = {1.0 - o.errors.scale, 1.0, 1.0 + o.errors.scale};
    detail::Evaluator evaluator(p, scales);
    DesignResult r;
    r.size = o.size;
    r.texel_um = o.texel_um;
    r.levels_um = p.levels_um;
    r.lambdas_um = p.lambdas_um;
    bool stopped = false;
    const std::function<void(const DesignStep&)> report = [&](const DesignStep& s) {
        r.curve.push_back(s);
        if (on_step && !on_step(s)) stopped = true;
    };

    p.target->reset_multipliers();
    RelaxedLevels relaxed = relaxed_levels(p, evaluator, report, stopped);
    std::vector<int> level = std::move(relaxed.level);
    const auto refine_start = Clock::now();
    RefineLoss refine_loss(p, evaluator, scales.size());
    ConstrainedRefine constrained;
    double loss = refine_constrained(p, evaluator, refine_loss, level, report, stopped, constrained);
    const double refine_seconds = seconds_since(refine_start);
    const BrightnessTrade trade =
        trade_for_brightness(p, evaluator, refine_loss, level, relaxed.latent, loss, report, stopped);

    r.level = level;
    const bool free_step = step_is_free(p);
    if (free_step) r.levels_um = level_heights(o.levels, evaluator.step_um());
    r.heights_um.resize(level.size());
    for (std::size_t t = 0; t < level.size(); ++t) r.heights_um[t] = r.levels_um[static_cast<std::size_t>(level[t])];

    const auto metrics_start = Clock::now();
    const ReliefScores scores = score_relief(p, evaluator, r);
    const double metrics_seconds = seconds_since(metrics_start);
    draw_pictures(p, scores, r);

    nlohmann::json j = design_json(p, r, relaxed, scores, loss, stopped);
    if (trade.considered) j["brightness_trade"] = brightness_trade_json(p, trade);
    const std::vector<std::string> colour_notes =
        o.target.kind == DesignKind::Colour ? add_colour_reach(p, scores, survey_views, j) : std::vector<std::string>{};
    j["notes"] = p.notes;
    j["start"] = p.start_level.empty() ? "random (seed)" : "the given relief (start_heights_um, --start)";
    if (free_step) {
        const double start_um = p.levels_um[1] - p.levels_um[0], final_um = evaluator.step_um();
        j["level_step"] = {{"what", std::string("the anti-mirror's level step, a design variable: started on ") +
                                        (p.start_level.empty() ? "the rule's step" : "the start relief's step") +
                                        " and moved with the texels by its gradient, (levels - 1) x step <= height_range_um"},
                           {"start_um", start_um},
                           {"final_um", final_um}};
        j["notes"].push_back("level step " + four_digits(final_um) + " um (top level " +
                             four_digits(final_um * (o.levels - 1)) + " um), designed from the " +
                             (p.start_level.empty() ? "rule's " : "start relief's ") +
                             four_digits(start_um) + " um");
    }
    for (const std::string& note : colour_notes) j["notes"].push_back(note);
    // A constrained target's limits, checked on the exported relief's exact scalar diffraction.
    j["warnings"] = p.target->broken_limits(scores.exact);
    if (p.target->constrained()) {
        j["constraint_loop"] = p.target->constraints_json();
        j["constraint_loop"]["relaxed_updates"] = relaxed.multiplier_updates;
        j["constraint_loop"]["refine_updates"] = constrained.updates;
        j["constraint_loop"]["repair_blocks"] = constrained.repair_blocks;
        j["constraint_loop"]["limits_met"] = j["warnings"].empty();
    }
    // A dim colour the trade did not bring to the brightness.
    for (const std::string& w : brightness_trade_warnings(p, trade, j["metrics"]["exact"])) j["warnings"].push_back(w);
    j["timings_s"] = {{"relaxed", relaxed.seconds}, {"refine", refine_seconds}, {"brightness_trade", trade.seconds},
                      {"metrics", metrics_seconds}, {"total", seconds_since(start)}};
    r.metrics_json = j.dump(2);
    return r;
}
}  // namespace

}  // namespace wavebrdf
