#pragma once
// What the design tests set up alike: designs and plates small enough for a unit test, and the
// light a relief sends into a view cone, scored independently of the run by exact_orders.
#include <array>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "wavebrdf/design.h"
#include "wavebrdf/design_plate.h"
#include "wavebrdf/design_run.h"

namespace wavebrdf::test {

// A design of a 16 × 16 tile (texels of 0.5 µm) under white light at 8 wavelengths, with no survey
// of other views: `target` as --target spells it, the levels and the schedule given.
inline DesignOptions small_design(const std::string& target, int levels, int iterations, int refine_passes) {
    DesignOptions o;
    o.target = parse_design_target(target);
    o.size = 16;
    o.levels = levels;
    o.spectral = 8;
    o.iterations = iterations;
    o.refine_passes = refine_passes;
    o.survey_views = false;
    return o;
}

// A picture from 8-bit sRGB triples (row-major).
inline PlatePicture picture(int rows, int cols, const std::vector<std::array<int, 3>>& pixels) {
    PlatePicture p;
    p.rows = rows;
    p.cols = cols;
    for (const auto& px : pixels)
        for (int c : px) p.srgb8.push_back(static_cast<std::uint8_t>(c));
    return p;
}

// A plate of the palette green and magenta (view cone 0.1, texels of 0.5 µm) with the tile, its
// levels and the schedule given; its picture and pixel size are the caller's.
inline PlateOptions small_plate(int size, int spectral, int levels, int iterations, int refine_passes) {
    PlateOptions o;
    o.design.size = size;
    o.design.texel_um = 0.5;
    o.design.spectral = spectral;
    o.design.levels = levels;
    o.design.view_cone = 0.1;
    o.design.iterations = iterations;
    o.design.refine_passes = refine_passes;
    o.palette = parse_palette("#00FF00;#FF00FF");
    return o;
}

// Per wavelength, the power exact_orders sends from the relief `h` (size² texels, normal light)
// into the cone |ω − view| ≤ cone, per unit incident power (as the colour targets count it).
inline std::vector<double> cone_power(const std::vector<double>& h, int size, double texel_um,
                                      const std::vector<double>& lambdas, std::array<double, 2> view, double cone) {
    const auto orders = exact_orders(h, size, texel_um, {0.0, 0.0}, lambdas);
    std::vector<double> r(orders.size(), 0.0);
    for (std::size_t w = 0; w < orders.size(); ++w)
        for (std::size_t q = 0; q < orders[w].power.size(); ++q)
            if (std::hypot(orders[w].omega_x[q] - view[0], orders[w].omega_y[q] - view[1]) <= cone)
                r[w] += orders[w].power[q] * orders[w].kirchhoff_total;
    return r;
}

// The cone colour of a relief: Y and u′v′ of cone_power.
inline std::array<double, 3> cone_colour(const std::vector<double>& h, int size, double texel_um,
                                         const std::vector<double>& lambdas, std::array<double, 2> view, double cone) {
    const auto xyz = reflectance_xyz(lambdas, cone_power(h, size, texel_um, lambdas, view, cone));
    const auto uv = xyz_to_uv(xyz);
    return {xyz[1], uv[0], uv[1]};
}

}  // namespace wavebrdf::test
