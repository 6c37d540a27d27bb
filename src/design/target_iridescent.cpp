// The iridescent target (docs/design.md): a list of (view direction, colour) pairs under white
// light, each pair's view cone scored as the colour target scores its one cone.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "design/target_more.h"
#include "wavebrdf/design.h"
#include "wavebrdf/input_files.h"
#include "wavebrdf/spectrum.h"
#include "wavebrdf/text.h"

namespace wavebrdf::detail {

namespace {

constexpr std::size_t k_max_spec_bytes = 64 * 1024;
constexpr int k_max_pairs = 16;

// The deepest nesting of arrays and objects in `text` (outside strings): a spec nests four deep,
// and refusing deeper text before parsing keeps a hostile file from recursing through the parser.
int nesting_depth(const std::string& text) {
    int depth = 0, deepest = 0;
    bool in_string = false, escaped = false;
    for (char c : text) {
        if (in_string) {
            if (escaped) escaped = false;
            else if (c == '\\') escaped = true;
            else if (c == '"') in_string = false;
            continue;
        }
        if (c == '"') in_string = true;
        else if (c == '[' || c == '{') deepest = std::max(deepest, ++depth);
        else if (c == ']' || c == '}') --depth;
    }
    return deepest;
}

class Iridescent final : public Target {
public:
    explicit Iridescent(const IridescentSpec& spec)
        : m_spec(spec),
          m_xyz_weights(colour_xyz_weights(spec.lambdas_um)),
          m_tolerance(spec.rgb.size(), spec.delta_uv_tolerance) {
        for (const auto& rgb : spec.rgb) m_target_uv.push_back(xyz_to_uv(linear_srgb_to_xyz(rgb)));
    }
    int groups() const override { return static_cast<int>(m_spec.rgb.size()); }
    bool incident_power() const override { return true; }
    // Per pair: the run's brightness trade raises only the tolerances of the pairs that are dim.
    void set_delta_uv_tolerance(std::size_t cone, double tolerance) override {
        if (cone < m_tolerance.size()) m_tolerance[cone] = tolerance;
    }

    void assign(const std::vector<OrderSet>& sets) override {
        m_members.assign(sets.size(), {});
        const double c2 = m_spec.view_cone * m_spec.view_cone;
        std::vector<std::size_t> count(m_spec.view_offsets.size(), 0);
        for (std::size_t w = 0; w < sets.size(); ++w) {
            const OrderSet& s = sets[w];
            m_members[w].assign(s.size(), {{-1, -1}});
            for (std::size_t o = 0; o < s.size(); ++o)
                for (std::size_t q = 0; q < m_spec.view_offsets.size(); ++q) {
                    const double dx = s.dx(o) - m_spec.view_offsets[q][0], dy = s.dy(o) - m_spec.view_offsets[q][1];
                    if (dx * dx + dy * dy <= c2) {
                        m_members[w][o][0] = static_cast<int>(q);
                        ++count[q];
                    }
                }
        }
        // A cone between the orders of every wavelength can receive no light whatever the relief.
        for (std::size_t q = 0; q < count.size(); ++q)
            if (count[q] == 0 && !sets.empty())
                throw std::invalid_argument("iridescent pair " + std::to_string(q + 1) + ": its view cone of --view-cone " +
                                            num(m_spec.view_cone) + " holds no diffraction order of the tile (period " +
                                            num(sets[0].period_um) + " um) at any wavelength; expected a larger --size "
                                            "or --view-cone");
    }

    std::array<double, 3> xyz(const Fractions& f, std::size_t q) const { return cone_xyz(m_xyz_weights, f, q); }

    // The sum over the pairs of the colour target's loss, each at its pair's tolerance.
    double loss(const Fractions& f, Fractions* gradient) const override {
        const std::size_t n = f.size(), P = m_spec.rgb.size();
        if (gradient) gradient->assign(n, std::vector<double>(P, 0.0));
        double total = 0.0;
        for (std::size_t q = 0; q < P; ++q) {
            std::array<double, 3> g{};
            total += colour_loss(xyz(f, q), m_target_uv[q], gradient ? &g : nullptr, m_tolerance[q]);
            if (!gradient) continue;
            for (std::size_t l = 0; l < n; ++l)
                for (std::size_t c = 0; c < 3; ++c) (*gradient)[l][q] += g[c] * m_xyz_weights[c * n + l];
        }
        return total;
    }

    nlohmann::json metrics(const Fractions& f) const override {
        const std::array<double, 9> m = xyz_to_linear_srgb();
        nlohmann::json pairs = nlohmann::json::array();
        std::vector<double> delta, y;
        for (std::size_t q = 0; q < m_spec.rgb.size(); ++q) {
            const auto X = xyz(f, q);
            const auto uv = xyz_to_uv(X);
            const std::array<double, 3> rgb{m[0] * X[0] + m[1] * X[1] + m[2] * X[2],
                                            m[3] * X[0] + m[4] * X[1] + m[5] * X[2],
                                            m[6] * X[0] + m[7] * X[1] + m[8] * X[2]};
            std::vector<double> reflectance;
            for (const auto& g : f) reflectance.push_back(g[q]);
            delta.push_back(std::hypot(uv[0] - m_target_uv[q][0], uv[1] - m_target_uv[q][1]));
            y.push_back(X[1]);
            pairs.push_back({{"delta_uv", delta.back()},
                             {"luminous_efficiency", X[1]},
                             {"uv", {uv[0], uv[1]}},
                             {"target_uv", {m_target_uv[q][0], m_target_uv[q][1]}},
                             {"linear_srgb", {rgb[0], rgb[1], rgb[2]}},
                             {"reflectance", reflectance}});
        }
        std::vector<double> sorted = delta;
        std::sort(sorted.begin(), sorted.end());
        const std::size_t k = sorted.size();
        const double median = k == 0 ? 0.0 : (k % 2 ? sorted[k / 2] : 0.5 * (sorted[k / 2 - 1] + sorted[k / 2]));
        return {{"delta_uv_worst", k ? sorted.back() : 0.0},
                {"delta_uv_median", median},
                {"luminous_efficiency_worst", y.empty() ? 0.0 : *std::min_element(y.begin(), y.end())},
                {"delta_uv", delta},
                {"luminous_efficiency", y},
                {"pairs", pairs}};
    }

private:
    IridescentSpec m_spec;
    std::vector<double> m_xyz_weights;
    std::vector<double> m_tolerance;  // per pair
    std::vector<std::array<double, 2>> m_target_uv;
};

}  // namespace

std::array<int, 3> parse_srgb8(const std::string& colour, const std::string& what) {
    bool ok = colour.size() == 7 && colour[0] == '#';
    for (std::size_t i = 1; ok && i < 7; ++i) ok = std::isxdigit(static_cast<unsigned char>(colour[i])) != 0;
    if (!ok) throw std::invalid_argument(what + ": colour '" + colour + "' is not an sRGB colour; expected #RRGGBB (hex digits)");
    std::array<int, 3> c{};
    for (std::size_t k = 0; k < 3; ++k) c[k] = std::stoi(colour.substr(1 + 2 * k, 2), nullptr, 16);
    if (c == std::array<int, 3>{0, 0, 0})
        throw std::invalid_argument(what + ": black has no chromaticity; expected a colour");
    return c;
}

DesignTarget read_iridescent_target(const std::string& text, const std::string& path) {
    const std::string where = "--target '" + text + "'";
    if (path.empty()) throw std::invalid_argument(where + " names no file; expected iridescent:SPEC.json");
    try {
        check_readable_file(path);
    } catch (const std::runtime_error& e) {
        throw std::invalid_argument(where + ": " + e.what());
    }
    std::ifstream in(path, std::ios::binary);
    if (!in) throw std::invalid_argument(where + ": cannot open '" + path + "'");
    std::string bytes(k_max_spec_bytes + 1, '\0');
    in.read(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    bytes.resize(static_cast<std::size_t>(in.gcount()));
    const std::string file = path + ": ";
    if (bytes.size() > k_max_spec_bytes)
        throw std::invalid_argument(file + "more than " + std::to_string(k_max_spec_bytes) +
                                    " bytes; expected a small JSON spec (docs/design.md)");
    if (nesting_depth(bytes) > 4)
        throw std::invalid_argument(file + "nested deeper than a spec; expected {\"pairs\": [{\"view\": [x, y], "
                                           "\"colour\": \"#RRGGBB\"}, ...]}");
    nlohmann::json doc;
    try {
        doc = nlohmann::json::parse(bytes);
    } catch (const nlohmann::json::exception& e) {
        std::string what = e.what();
        if (const auto nl = what.find('\n'); nl != std::string::npos) what.resize(nl);
        throw std::invalid_argument(file + "not valid JSON (" + what + ")");
    }
    const std::string shape = "expected {\"pairs\": [{\"view\": [x, y], \"colour\": \"#RRGGBB\"}, ...]}";
    if (!doc.is_object() || !doc.contains("pairs") || !doc["pairs"].is_array())
        throw std::invalid_argument(file + "no array 'pairs'; " + shape);
    for (const auto& item : doc.items())
        if (item.key() != "pairs") throw std::invalid_argument(file + "unknown field '" + item.key() + "'; " + shape);
    const auto& pairs = doc["pairs"];
    if (pairs.empty() || pairs.size() > static_cast<std::size_t>(k_max_pairs))
        throw std::invalid_argument(file + std::to_string(pairs.size()) + " pairs; expected 1 to " +
                                    std::to_string(k_max_pairs));
    DesignTarget t;
    t.kind = DesignKind::Iridescent;
    t.text = text;
    t.spec_file = path;
    for (std::size_t k = 0; k < pairs.size(); ++k) {
        const std::string at = file + "pair " + std::to_string(k + 1) + ": ";
        const auto& p = pairs[k];
        if (!p.is_object()) throw std::invalid_argument(at + "not an object; " + shape);
        for (const auto& item : p.items())
            if (item.key() != "view" && item.key() != "colour" && item.key() != "color")
                throw std::invalid_argument(at + "unknown field '" + item.key() + "'; expected view and colour");
        if (!p.contains("view") || !p["view"].is_array() || p["view"].size() != 2 || !p["view"][0].is_number() ||
            !p["view"][1].is_number())
            throw std::invalid_argument(at + "'view' is " + (p.contains("view") ? p["view"].dump() : "missing") +
                                        "; expected [x, y], a projected view direction");
        IridescentPair pair;
        pair.view = {p["view"][0].get<double>(), p["view"][1].get<double>()};
        if (!(std::isfinite(pair.view[0]) && std::isfinite(pair.view[1]) && std::hypot(pair.view[0], pair.view[1]) < 1.0))
            throw std::invalid_argument(at + "view (" + num(pair.view[0]) + ", " + num(pair.view[1]) +
                                        ") is outside the visible disk; expected |view| < 1");
        const char* key = p.contains("colour") ? "colour" : "color";
        if (!p.contains(key) || !p[key].is_string())
            throw std::invalid_argument(at + "'colour' is " + (p.contains(key) ? p[key].dump() : "missing") +
                                        "; expected \"#RRGGBB\"");
        pair.srgb8 = parse_srgb8(p[key].get<std::string>(), at.substr(0, at.size() - 2));
        for (std::size_t c = 0; c < 3; ++c) pair.linear_rgb[c] = srgb_decode(pair.srgb8[c] / 255.0);
        t.pairs.push_back(pair);
    }
    return t;
}

std::unique_ptr<Target> make_iridescent(const IridescentSpec& spec) { return std::make_unique<Iridescent>(spec); }

}  // namespace wavebrdf::detail
