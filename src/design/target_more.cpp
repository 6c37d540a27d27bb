// The run's side of the iridescent and brdf targets (target_more.h): their options checked,
// their lights, memory, target pictures and design.json description.
#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "design/target_more.h"
#include "wavebrdf/constants.h"
#include "wavebrdf/table.h"
#include "wavebrdf/text.h"

namespace wavebrdf::detail {

namespace {

// The table lights (row a, column b) a brdf design matches: every rendered light when there are at
// most k_max_brdf_lights, else the rendered light nearest the design's light.
std::vector<std::array<int, 2>> table_lights(const DesignOptions& o) {
    const BrdfTable& t = *o.target.table;
    std::vector<std::array<int, 2>> all;
    for (int a = 0; a < t.spec.lights.rows; ++a)
        for (int b = 0; b < t.spec.lights.cols; ++b)
            if (t.rendered[static_cast<std::size_t>(a) * static_cast<std::size_t>(t.spec.lights.cols) + static_cast<std::size_t>(b)])
                all.push_back({a, b});
    if (all.size() <= static_cast<std::size_t>(k_max_brdf_lights)) return all;
    auto distance = [&](const std::array<int, 2>& l) {
        return std::hypot(t.light_x[static_cast<std::size_t>(l[0])] - o.omega_i[0],
                          t.light_y[static_cast<std::size_t>(l[1])] - o.omega_i[1]);
    };
    return {*std::min_element(all.begin(), all.end(),
                              [&](const auto& x, const auto& y) { return distance(x) < distance(y); })};
}

}  // namespace

std::vector<std::array<double, 2>> design_lights(const DesignOptions& o) {
    if (o.target.kind != DesignKind::Brdf || !o.target.table) return {o.omega_i};
    const BrdfTable& t = *o.target.table;
    std::vector<std::array<double, 2>> lights;
    for (const auto& l : table_lights(o))
        lights.push_back({t.light_x[static_cast<std::size_t>(l[0])], t.light_y[static_cast<std::size_t>(l[1])]});
    return lights;
}

double more_target_bytes(const DesignOptions& o) {
    if (o.target.kind != DesignKind::Brdf || !o.target.table) return 0.0;
    const double n2 = static_cast<double>(o.target.table->spec.resolution) * o.target.table->spec.resolution;
    const double sets = static_cast<double>(design_lights(o).size() * o.target.table->spec.lambdas_um.size());
    // The fractions and their gradients (about six copies of sets × n² doubles), the target's entries.
    return 6.0 * 8.0 * sets * n2 + 12.0 * n2 * static_cast<double>(design_lights(o).size());
}

void prepare_more_target(PreparedDesign& p) {
    DesignOptions& o = p.options;
    if (o.target.kind == DesignKind::Iridescent) {
        if (!(o.view_cone >= 1e-3 && o.view_cone <= 0.5))
            throw std::domain_error("--view-cone " + num(o.view_cone) + " is out of range; expected 1e-3 to 0.5");
        if (!(o.delta_uv_tolerance >= 0.0 && o.delta_uv_tolerance <= 0.1))
            throw std::domain_error("--delta-uv-tolerance " + num(o.delta_uv_tolerance) +
                                    " is out of range; expected 0 to 0.1");
        if (!(o.delta_uv_ceiling >= 0.0 && o.delta_uv_ceiling <= 0.1))
            throw std::domain_error("--delta-uv-ceiling " + num(o.delta_uv_ceiling) +
                                    " is out of range; expected 0 to 0.1");
        if (p.lambdas_um.size() < 3)
            throw std::invalid_argument("--target " + o.target.text +
                                        " needs white light; give --spectral N (N >= 3), not one --lambda-um");
        if (o.target.pairs.empty()) throw std::invalid_argument("--target " + o.target.text + " has no pairs");
        const std::array<double, 2> mirror{-o.omega_i[0], -o.omega_i[1]};
        IridescentSpec spec;
        spec.view_cone = o.view_cone;
        spec.lambdas_um = p.lambdas_um;
        spec.delta_uv_tolerance = o.delta_uv_tolerance;
        const auto& pairs = o.target.pairs;
        for (std::size_t k = 0; k < pairs.size(); ++k) {
            const auto& v = pairs[k].view;
            if (!(std::hypot(v[0], v[1]) + o.view_cone < 1.0))
                throw std::domain_error("iridescent pair " + std::to_string(k + 1) + ": view (" + num(v[0]) + ", " +
                                        num(v[1]) + ") with --view-cone " + num(o.view_cone) +
                                        " reaches outside the visible disk; expected |view| + cone < 1");
            for (std::size_t j = 0; j < k; ++j)
                if (std::hypot(v[0] - pairs[j].view[0], v[1] - pairs[j].view[1]) <= 2.0 * o.view_cone)
                    throw std::invalid_argument("iridescent pairs " + std::to_string(j + 1) + " and " +
                                                std::to_string(k + 1) + ": their view cones of --view-cone " +
                                                num(o.view_cone) + " overlap; expected views more than " +
                                                num(2.0 * o.view_cone) + " apart");
            spec.view_offsets.push_back({v[0] - mirror[0], v[1] - mirror[1]});
            spec.rgb.push_back(pairs[k].linear_rgb);
        }
        p.target = make_iridescent(spec);
        return;
    }
    if (o.target.kind == DesignKind::Brdf) {
        if (!o.target.table) throw std::invalid_argument("--target " + o.target.text + " without a table");
        if (o.spectral != 0)
            throw std::invalid_argument("--spectral " + std::to_string(o.spectral) + " with --target " + o.target.text +
                                        ": a brdf target's wavelengths are its table's; expected no --spectral");
        const BrdfTable& t = *o.target.table;
        const auto indices = table_lights(o);
        BrdfSpec spec;
        spec.resolution = t.spec.resolution;
        spec.lambdas_um = t.spec.lambdas_um;
        spec.lights = design_lights(o);
        const std::size_t n2 = static_cast<std::size_t>(t.spec.resolution) * static_cast<std::size_t>(t.spec.resolution);
        for (const auto& l : indices) {
            const std::size_t entry =
                static_cast<std::size_t>(l[0]) * static_cast<std::size_t>(t.spec.lights.cols) + static_cast<std::size_t>(l[1]);
            spec.values.emplace_back(t.values.begin() + static_cast<std::ptrdiff_t>(entry * n2 * 3),
                                     t.values.begin() + static_cast<std::ptrdiff_t>((entry + 1) * n2 * 3));
        }
        const std::size_t rendered = static_cast<std::size_t>(std::count(t.rendered.begin(), t.rendered.end(), 1));
        if (rendered > indices.size())
            p.notes.push_back("the table has " + std::to_string(rendered) + " lights, more than the " +
                              std::to_string(k_max_brdf_lights) + " a design matches at once: matched at its light (" +
                              num(spec.lights[0][0]) + ", " + num(spec.lights[0][1]) + "), the nearest to the design's light");
        else if (indices.size() > 1)
            p.notes.push_back("matched at every one of the table's " + std::to_string(indices.size()) +
                              " lights; pictures show the first, (" + num(spec.lights[0][0]) + ", " +
                              num(spec.lights[0][1]) + ")");
        o.omega_i = spec.lights[0];
        p.target = make_brdf(spec);
        return;
    }
    throw std::invalid_argument("--target " + o.target.text + " is not an iridescent or brdf target");
}

double more_picture_extent(const DesignOptions& o) {
    if (o.target.kind == DesignKind::Iridescent) {
        double e = 0.0;
        for (const auto& pair : o.target.pairs)
            e = std::max(e, std::max(std::abs(pair.view[0] + o.omega_i[0]), std::abs(pair.view[1] + o.omega_i[1])));
        return std::min(1.0, e + 2.0 * o.view_cone);
    }
    return 1.0;
}

void more_target_picture(const DesignOptions& o, int n, double extent, std::vector<float>& picture) {
    picture.assign(static_cast<std::size_t>(n) * static_cast<std::size_t>(n) * 3, 0.0f);
    const std::array<double, 2> mirror{-o.omega_i[0], -o.omega_i[1]};
    const BrdfTable* t = o.target.kind == DesignKind::Brdf ? o.target.table.get() : nullptr;
    const auto first = t ? table_lights(o).front() : std::array<int, 2>{0, 0};
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
            const double dx = (i + 0.5) / n * 2.0 * extent - extent, dy = (j + 0.5) / n * 2.0 * extent - extent;
            std::array<double, 3> c{0.0, 0.0, 0.0};
            if (o.target.kind == DesignKind::Iridescent) {
                for (const auto& pair : o.target.pairs)
                    if (std::hypot(mirror[0] + dx - pair.view[0], mirror[1] + dy - pair.view[1]) <= o.view_cone)
                        c = pair.linear_rgb;
            } else if (t) {
                const double wx = mirror[0] + dx, wy = mirror[1] + dy;
                const int r = t->spec.resolution;
                if (wx * wx + wy * wy < 1.0) {
                    const int p = std::clamp(static_cast<int>(std::floor((wx + 1.0) / 2.0 * r)), 0, r - 1);
                    const int q = std::clamp(static_cast<int>(std::floor((wy + 1.0) / 2.0 * r)), 0, r - 1);
                    const std::size_t entry = static_cast<std::size_t>(first[0]) * static_cast<std::size_t>(t->spec.lights.cols) +
                                              static_cast<std::size_t>(first[1]);
                    const std::size_t at = ((entry * static_cast<std::size_t>(r) + static_cast<std::size_t>(p)) *
                                                static_cast<std::size_t>(r) + static_cast<std::size_t>(q)) * 3;
                    c = {double(t->values[at]), double(t->values[at + 1]), double(t->values[at + 2])};
                }
            }
            for (std::size_t k = 0; k < 3; ++k)
                picture[(static_cast<std::size_t>(i) * static_cast<std::size_t>(n) + static_cast<std::size_t>(j)) * 3 + k] =
                    static_cast<float>(c[k]);
        }
}

void more_target_json(const DesignOptions& o, nlohmann::json& target) {
    if (o.target.kind == DesignKind::Iridescent) {
        nlohmann::json pairs = nlohmann::json::array();
        for (const auto& p : o.target.pairs)
            pairs.push_back({{"view", p.view}, {"srgb8", p.srgb8}, {"linear_rgb", p.linear_rgb}});
        target["pairs"] = pairs;
        target["view_cone"] = o.view_cone;
        target["delta_uv_tolerance"] = o.delta_uv_tolerance;
        target["delta_uv_ceiling"] = o.delta_uv_ceiling;
        target["spec_file"] = o.target.spec_file;
    } else if (o.target.kind == DesignKind::Brdf && o.target.table) {
        const BrdfTable& t = *o.target.table;
        target["table_file"] = o.target.table_file;
        target["table_source"] = t.source;
        target["resolution"] = t.spec.resolution;
        target["table_lights"] = {t.spec.lights.rows, t.spec.lights.cols};
        target["lights"] = design_lights(o);
        target["lambdas_um"] = t.spec.lambdas_um;
        target["binning"] = "each order's fraction of the reflected power over the pixel's projected solid angle (2/n)^2";
    }
}

}  // namespace wavebrdf::detail
