#pragma once
// Internal: the iridescent and brdf targets (target_iridescent.cpp, target_brdf.cpp) and what the
// run (design_run.cpp) asks of them where it dispatches on the target's kind.
#include <array>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "design/target.h"
#include "wavebrdf/design_run.h"

namespace wavebrdf::detail {

// `iridescent:SPEC.json` and `brdf:TABLE.exr` (docs/design.md); std::invalid_argument naming the
// file and what was expected.
DesignTarget read_iridescent_target(const std::string& text, const std::string& path);
DesignTarget read_brdf_target(const std::string& text, const std::string& path);
// The one-line parse of "#RRGGBB" (not black) used by the colour kinds; `what` leads the message.
std::array<int, 3> parse_srgb8(const std::string& colour, const std::string& what);

// The light directions the design's orders are built for: the design's light, or a brdf target's
// table lights (all its rendered lights when there are at most k_max_brdf_lights, else the one
// nearest the design's light). The order sets are light-major: set = light · wavelengths + wavelength.
constexpr int k_max_brdf_lights = 16;
std::vector<std::array<double, 2>> design_lights(const DesignOptions& o);

// Extra memory of a brdf target (its groups per order set), bytes; 0 for the other kinds.
double more_target_bytes(const DesignOptions& o);

// Checks an iridescent or brdf target's options and makes its Target (prepare_design); may set
// p.options.omega_i (a brdf target's first light) and add notes.
void prepare_more_target(PreparedDesign& p);

// The target picture over ±extent about the mirror direction (n² linear RGB, rows along ω_x).
double more_picture_extent(const DesignOptions& o);
void more_target_picture(const DesignOptions& o, int n, double extent, std::vector<float>& picture);
// design.json's description of the target.
void more_target_json(const DesignOptions& o, nlohmann::json& target);

// Iridescent: one group per pair (its view cone; the cones are disjoint), each scored as the
// colour target scores its cone.
struct IridescentSpec {
    std::vector<std::array<double, 2>> view_offsets;  // view − mirror direction, per pair
    std::vector<std::array<double, 3>> rgb;           // linear sRGB, per pair
    double view_cone = 0.05;
    std::vector<double> lambdas_um;
    double delta_uv_tolerance = 0.0;  // every pair's, as the colour target's (set_delta_uv_tolerance per pair)
};
std::unique_ptr<Target> make_iridescent(const IridescentSpec& spec);

// Brdf: one group per table pixel (i · n + j) for every order set; the set's lights and
// wavelengths light-major as design_lights.
struct BrdfSpec {
    int resolution = 0;                            // n: the table's ω_o pixels per side
    std::vector<double> lambdas_um;                // W wavelengths
    std::vector<std::array<double, 2>> lights;     // L lights
    std::vector<std::vector<float>> values;        // per light: n² · 3 f_r (1/sr), the table's entry
};
std::unique_ptr<Target> make_brdf(const BrdfSpec& spec);

}  // namespace wavebrdf::detail
