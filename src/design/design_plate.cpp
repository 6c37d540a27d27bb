// A spatially varying design (design_plate.h): a palette of tile designs laid out as a picture.
#include "wavebrdf/design_plate.h"

#include <png.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>
#include <unordered_map>

#include "core/random.h"
#include "design/engine.h"
#include "design/fabrication_json.h"
#include "design/png_input.h"
#include "design/target.h"
#include "wavebrdf/constants.h"
#include "wavebrdf/design.h"
#include "wavebrdf/fabrication.h"
#include "wavebrdf/heightfield.h"
#include "wavebrdf/io.h"
#include "wavebrdf/memory.h"
#include "wavebrdf/run_directory.h"
#include "wavebrdf/spectrum.h"
#include "wavebrdf/text.h"
#include "wavebrdf/version.h"

namespace wavebrdf {

namespace {

using Clock = std::chrono::steady_clock;
using detail::num;  // design/target.h

// A highlight: as much of the reflected light as possible into the view cone about the
// direction, on average over the wavelengths. Group 0 is the cone.
class Highlight final : public detail::Target {
public:
    Highlight(std::array<double, 2> offset, double cone) : m_offset(offset), m_cone(cone) {}
    int groups() const override { return 1; }
    void assign(const std::vector<detail::OrderSet>& sets) override {
        m_members.assign(sets.size(), {});
        for (std::size_t w = 0; w < sets.size(); ++w) {
            const auto& s = sets[w];
            m_members[w].assign(s.size(), {{-1, -1}});
            for (std::size_t o = 0; o < s.size(); ++o)
                if (std::hypot(s.dx(o) - m_offset[0], s.dy(o) - m_offset[1]) <= m_cone) m_members[w][o][0] = 0;
        }
    }
    double loss(const detail::Fractions& f, detail::Fractions* gradient) const override {
        const double W = static_cast<double>(f.size());
        double mean = 0.0;
        for (const auto& g : f) mean += g[0] / W;
        if (gradient) gradient->assign(f.size(), std::vector<double>(1, -1.0 / W));
        return 1.0 - mean;
    }
    nlohmann::json metrics(const detail::Fractions& f) const override {
        std::vector<double> cone;
        for (const auto& g : f) cone.push_back(g[0]);
        double mean = 0.0;
        for (double c : cone) mean += c / static_cast<double>(cone.size());
        return {{"cone_fraction", cone},
                {"cone_fraction_mean", mean},
                {"cone_fraction_worst", cone.empty() ? 0.0 : *std::min_element(cone.begin(), cone.end())}};
    }

private:
    std::array<double, 2> m_offset;
    double m_cone;
};

// CIELUV (D65 white, Y of white 1) of a linear sRGB colour.
std::array<double, 3> linear_srgb_to_luv(const std::array<double, 3>& rgb) {
    static const std::array<double, 2> white = xyz_to_uv(linear_srgb_to_xyz({1.0, 1.0, 1.0}));
    const auto xyz = linear_srgb_to_xyz(rgb);
    const double y = xyz[1];
    const double L = y > 216.0 / 24389.0 ? 116.0 * std::cbrt(y) - 16.0 : 24389.0 / 27.0 * y;
    const auto uv = xyz_to_uv(xyz);
    if (!(xyz[0] + 15.0 * xyz[1] + 3.0 * xyz[2] > 0.0)) return {0.0, 0.0, 0.0};
    return {L, 13.0 * L * (uv[0] - white[0]), 13.0 * L * (uv[1] - white[1])};
}

std::array<double, 3> pixel_linear(const std::uint8_t* p) {
    return {srgb_decode(p[0] / 255.0), srgb_decode(p[1] / 255.0), srgb_decode(p[2] / 255.0)};
}

std::array<double, 3> xyz_to_rgb(const std::array<double, 3>& x) {
    const std::array<double, 9> m = xyz_to_linear_srgb();
    return {m[0] * x[0] + m[1] * x[1] + m[2] * x[2], m[3] * x[0] + m[4] * x[1] + m[5] * x[2],
            m[6] * x[0] + m[7] * x[1] + m[8] * x[2]};
}

// The design options of one entry.
DesignOptions entry_options(const PlateOptions& o, const PaletteEntry& e, std::size_t index) {
    DesignOptions d = o.design;
    d.seed = detail::derive_seed(o.design.seed, index);
    if (e.direction) {
        d.target = parse_design_target("colour:#FFFFFF");  // replaced by the highlight (prepare_entry)
        d.view = e.omega;
    } else {
        d.target = parse_design_target("colour:" + e.text);
    }
    return d;
}

PreparedDesign prepare_entry(const PlateOptions& o, std::size_t index) {
    const PaletteEntry& e = o.palette[index];
    PreparedDesign p = prepare_design(entry_options(o, e, index));
    if (e.direction) {
        const std::array<double, 2> mirror{-o.design.omega_i[0], -o.design.omega_i[1]};
        auto target = std::make_shared<Highlight>(std::array<double, 2>{e.omega[0] - mirror[0], e.omega[1] - mirror[1]},
                                                  o.design.view_cone);
        target->assign(*p.order_sets);
        p.target = target;
    }
    return p;
}

std::vector<std::string> split_entries(const std::string& text) {
    std::vector<std::string> out;
    std::string cur;
    auto flush = [&] {
        if (cur.empty()) return;
        if (cur.rfind("dir:", 0) != 0) {
            // colours may be separated by commas
            std::stringstream ss(cur);
            std::string part;
            while (std::getline(ss, part, ','))
                if (!part.empty()) out.push_back(part);
        } else {
            out.push_back(cur);
        }
        cur.clear();
    };
    for (char c : text) {
        if (c == ';' || std::isspace(static_cast<unsigned char>(c))) flush();
        else cur.push_back(c);
    }
    flush();
    return out;
}

}  // namespace

std::vector<PaletteEntry> parse_palette(const std::string& text) {
    const auto bad = [&](const std::string& entry, const std::string& why) {
        return std::invalid_argument("--palette entry '" + entry + "' " + why +
                                     "; expected #RRGGBB colours or dir:X,Y directions (|(X, Y)| < 1)");
    };
    std::vector<PaletteEntry> out;
    for (const std::string& t : split_entries(text)) {
        PaletteEntry e;
        e.text = t;
        if (t.rfind("dir:", 0) == 0) {
            e.direction = true;
            const std::string rest = t.substr(4);
            const auto comma = rest.find(',');
            if (comma == std::string::npos) throw bad(t, "is not a direction");
            for (int k = 0; k < 2; ++k) {
                const std::string s = k == 0 ? rest.substr(0, comma) : rest.substr(comma + 1);
                char* end = nullptr;
                const double v = std::strtod(s.c_str(), &end);
                if (s.empty() || end != s.c_str() + s.size() || !std::isfinite(v)) throw bad(t, "is not a direction");
                e.omega[static_cast<std::size_t>(k)] = v;
            }
            if (!(std::hypot(e.omega[0], e.omega[1]) < 1.0)) throw bad(t, "lies outside the visible disk");
        } else {
            bool ok = t.size() == 7 && t[0] == '#';
            for (std::size_t i = 1; ok && i < 7; ++i) ok = std::isxdigit(static_cast<unsigned char>(t[i])) != 0;
            if (!ok) throw bad(t, "is not understood");
            for (int k = 0; k < 3; ++k) {
                e.srgb8[static_cast<std::size_t>(k)] = std::stoi(t.substr(static_cast<std::size_t>(1 + 2 * k), 2), nullptr, 16);
                e.linear_rgb[static_cast<std::size_t>(k)] = srgb_decode(e.srgb8[static_cast<std::size_t>(k)] / 255.0);
            }
            if (e.srgb8 == std::array<int, 3>{0, 0, 0}) throw bad(t, "is black, which has no chromaticity to design for");
        }
        for (const PaletteEntry& f : out) {
            if (f.direction != e.direction) throw bad(t, "mixes colours and directions in one palette");
            if ((e.direction && f.omega == e.omega) || (!e.direction && f.srgb8 == e.srgb8))
                throw bad(t, "repeats '" + f.text + "'");
        }
        out.push_back(e);
        if (static_cast<int>(out.size()) > k_max_palette_entries)
            throw std::invalid_argument("--palette has more than " + std::to_string(k_max_palette_entries) + " entries");
    }
    if (out.size() < 2)
        throw std::invalid_argument("--palette '" + text + "' has " + std::to_string(out.size()) +
                                    " entries; expected at least two (#RRGGBB colours or dir:X,Y directions)");
    return out;
}

PlatePicture read_plate_picture(const std::string& path, long long max_pixels) {
    png_image image{};
    detail::begin_png_read(image, path, "picture '" + path + "'");
    const long long pixels = static_cast<long long>(image.width) * image.height;
    if (image.width < 1 || image.height < 1 || image.width > k_max_picture_side || image.height > k_max_picture_side ||
        pixels > max_pixels) {
        png_image_free(&image);
        throw std::invalid_argument("picture '" + path + "' is " + std::to_string(image.width) + " x " +
                                    std::to_string(image.height) + " pixels; expected at most " +
                                    std::to_string(max_pixels) + " pixels (" + std::to_string(k_max_picture_side) +
                                    " a side) for this plate");
    }
    image.format = PNG_FORMAT_RGB;
    PlatePicture p;
    p.srgb8.resize(PNG_IMAGE_SIZE(image));
    if (!png_image_finish_read(&image, nullptr, p.srgb8.data(), 0, nullptr)) {
        const std::string message = image.message;
        png_image_free(&image);
        throw std::invalid_argument("picture '" + path + "' cannot be read: " + message);
    }
    p.rows = static_cast<int>(image.height);
    p.cols = static_cast<int>(image.width);
    p.file = path;
    return p;
}

int plate_pixel_texels(const DesignOptions& d, double plate_pixel_um) {
    if (!(d.size >= 2 && d.size <= 2048))
        throw std::domain_error("--size " + std::to_string(d.size) + " is out of range; expected 2 to 2048 texels");
    if (!(d.texel_um >= 0.05 && d.texel_um <= 100.0))
        throw std::domain_error("--texel-um " + num(d.texel_um) + " is out of range; expected 0.05 to 100 um");
    const double period = d.size * d.texel_um;
    if (plate_pixel_um == 0.0) return d.size;
    const double periods = plate_pixel_um / period;
    const double whole = std::round(periods);
    if (!(std::isfinite(periods) && whole >= 1.0 && whole <= 16384.0 && std::abs(periods - whole) <= 1e-6 * whole))
        throw std::domain_error("--plate-pixel-um " + num(plate_pixel_um) + " is not a whole number of tile periods; "
                                "expected a multiple of --size x --texel-um = " + num(period) + " um");
    return static_cast<int>(whole) * d.size;
}

PreparedPlate prepare_plate(const PlateOptions& options) {
    const PlateOptions& o = options;
    PreparedPlate p;
    p.options = o;
    if (o.palette.size() < 2) throw std::invalid_argument("--palette needs at least two entries");
    if (o.design.spectral < 3)
        throw std::invalid_argument("--target image needs white light; give --spectral N (N >= 3)");
    if (o.picture.rows < 1 || o.picture.cols < 1 ||
        o.picture.srgb8.size() != static_cast<std::size_t>(o.picture.rows) * static_cast<std::size_t>(o.picture.cols) * 3)
        throw std::invalid_argument("--target image: the picture is empty or its size does not match its pixels");
    // Every entry's options through the single-tile designer's checks (orders built and dropped).
    double largest = 0.0;
    for (std::size_t e = 0; e < o.palette.size(); ++e) {
        const DesignOptions d = entry_options(o, o.palette[e], e);
        largest = std::max(largest, estimate_design_bytes(d));
    }
    p.pixel_texels = plate_pixel_texels(o.design, o.plate_pixel_um);
    const long long rows = static_cast<long long>(o.picture.rows) * p.pixel_texels;
    const long long cols = static_cast<long long>(o.picture.cols) * p.pixel_texels;
    if (rows > k_max_exr_side || cols > k_max_exr_side || rows * cols > k_max_fabrication_texels)
        throw std::domain_error("the plate would be " + std::to_string(rows) + " x " + std::to_string(cols) +
                                " texels (picture " + std::to_string(o.picture.rows) + " x " +
                                std::to_string(o.picture.cols) + " pixels of " + std::to_string(p.pixel_texels) +
                                " texels); expected at most " + std::to_string(k_max_exr_side) + " a side");
    p.rows = static_cast<int>(rows);
    p.cols = static_cast<int>(cols);
    const double texels = static_cast<double>(rows) * static_cast<double>(cols);
    const double pixels = static_cast<double>(o.picture.rows) * o.picture.cols;
    const double panels = o.palette.front().direction ? static_cast<double>(o.palette.size()) + 1.0 : 2.0;
    // heights (8), levels (4), heights.exr's values and heightfield (16), the masks' levels (4),
    // rows of the writers; the picture, its assignment and the panels (12 bytes a pixel each).
    p.estimated_bytes = largest + 40.0 * texels + pixels * (7.0 + 12.0 * panels) +
                        static_cast<double>(o.palette.size()) * 8.0 * o.design.size * o.design.size;
    require_memory(p.estimated_bytes, memory_limit(o.design.max_memory_gb), "the plate");
    (void)prepare_entry(o, 0);  // the first entry's orders: the options' own checks, before any work

    // Map the pixels.
    const std::size_t K = o.palette.size(), P = static_cast<std::size_t>(pixels);
    p.assignment.assign(P, 0);
    p.pixels_per_entry.assign(K, 0);
    if (!o.palette.front().direction) {
        p.mapping = "nearest palette colour in CIELUV (D65), Delta E*uv from the picture pixel's colour";
        std::vector<std::array<double, 3>> luv(K);
        for (std::size_t e = 0; e < K; ++e) luv[e] = linear_srgb_to_luv(o.palette[e].linear_rgb);
        std::unordered_map<std::uint32_t, int> cache;
        for (std::size_t i = 0; i < P; ++i) {
            const std::uint8_t* px = &o.picture.srgb8[3 * i];
            const std::uint32_t key = (std::uint32_t{px[0]} << 16) | (std::uint32_t{px[1]} << 8) | px[2];
            auto it = cache.find(key);
            if (it == cache.end()) {
                const auto c = linear_srgb_to_luv(pixel_linear(px));
                int best = 0;
                double best_d = 1e300;
                for (std::size_t e = 0; e < K; ++e) {
                    const double d = std::hypot(c[0] - luv[e][0], c[1] - luv[e][1], c[2] - luv[e][2]);
                    if (d < best_d) {
                        best_d = d;
                        best = static_cast<int>(e);
                    }
                }
                it = cache.emplace(key, best).first;
            }
            p.assignment[i] = it->second;
        }
    } else {
        p.mapping = "the picture pixel's luminance Y in K equal bands, darkest to the first entry";
        for (std::size_t i = 0; i < P; ++i) {
            const double y = linear_srgb_to_xyz(pixel_linear(&o.picture.srgb8[3 * i]))[1];
            p.assignment[i] = std::min(static_cast<int>(K) - 1, std::max(0, static_cast<int>(y * static_cast<double>(K))));
        }
    }
    for (int a : p.assignment) ++p.pixels_per_entry[static_cast<std::size_t>(a)];
    for (std::size_t e = 0; e < K; ++e)
        if (p.pixels_per_entry[e] == 0) p.notes.push_back("palette entry " + o.palette[e].text + " takes no pixel; not designed");
    return p;
}

PlateResult run_plate(const PreparedPlate& p, const std::function<bool(int, const DesignStep&)>& on_step) {
    const PlateOptions& o = p.options;
    const auto start = Clock::now();
    const std::size_t K = o.palette.size();
    const int N = o.design.size;
    PlateResult r;
    r.rows = p.rows;
    r.cols = p.cols;
    r.texel_um = o.design.texel_um;
    r.tiles.resize(K);
    std::vector<double> lambdas;
    nlohmann::json entries = nlohmann::json::array();

    // Views: the colour palette's one view, or each direction entry's.
    const std::array<double, 2> mirror{-o.design.omega_i[0], -o.design.omega_i[1]};
    std::vector<std::array<double, 2>> views;
    if (o.palette.front().direction) {
        for (const auto& e : o.palette) {
            views.push_back(e.omega);
            r.view_names.push_back("view " + e.text);
        }
    } else {
        views.push_back(o.design.view ? *o.design.view : mirror);
        r.view_names.push_back("view (" + num(views[0][0]) + ", " + num(views[0][1]) + ")");
    }
    // appearance_xyz[e][v]: the XYZ of entry e's tile into view v's cone (fractions of the incident light).
    std::vector<std::vector<std::array<double, 3>>> appearance_xyz(K, std::vector<std::array<double, 3>>(views.size(), {0.0, 0.0, 0.0}));

    std::vector<std::string> plate_warnings;
    for (std::size_t e = 0; e < K; ++e) {
        if (p.pixels_per_entry[e] == 0) {
            entries.push_back({{"entry", o.palette[e].text}, {"pixels", 0}});
            continue;
        }
        PreparedDesign pd = prepare_entry(o, e);
        pd.options.survey_views = false;
        DesignResult d = run_design(pd, [&](const DesignStep& s) { return on_step ? on_step(static_cast<int>(e), s) : true; });
        d.target_picture.clear();
        d.far_field_picture.clear();
        if (r.levels_um.empty()) r.levels_um = d.levels_um;
        if (d.levels_um != r.levels_um) throw std::logic_error("plate entries designed on different levels");
        lambdas = d.lambdas_um;
        // The tile by exact scalar diffraction (design.h), into every view's cone.
        const auto orders = exact_orders(d.heights_um, N, o.design.texel_um, o.design.omega_i, d.lambdas_um);
        nlohmann::json views_json = nlohmann::json::array();
        for (std::size_t v = 0; v < views.size(); ++v) {
            std::vector<double> reflectance(orders.size(), 0.0);
            for (std::size_t w = 0; w < orders.size(); ++w)
                for (std::size_t q = 0; q < orders[w].power.size(); ++q)
                    if (std::hypot(orders[w].omega_x[q] - views[v][0], orders[w].omega_y[q] - views[v][1]) <= o.design.view_cone)
                        reflectance[w] += orders[w].power[q] * orders[w].kirchhoff_total;  // of the incident power
            appearance_xyz[e][v] = reflectance_xyz(d.lambdas_um, reflectance);
            const auto uv = xyz_to_uv(appearance_xyz[e][v]);
            nlohmann::json vj{{"view", views[v]}, {"xyz", appearance_xyz[e][v]}, {"uv", uv},
                              {"luminous_efficiency", appearance_xyz[e][v][1]},
                              {"linear_srgb", xyz_to_rgb(appearance_xyz[e][v])}};
            if (!o.palette[e].direction) {
                const auto t = xyz_to_uv(linear_srgb_to_xyz(o.palette[e].linear_rgb));
                vj["delta_uv"] = std::hypot(uv[0] - t[0], uv[1] - t[1]);
            }
            views_json.push_back(vj);
        }
        const nlohmann::json dj = nlohmann::json::parse(d.metrics_json);
        entries.push_back({{"entry", o.palette[e].text},
                           {"pixels", p.pixels_per_entry[e]},
                           {"seed", dj["seed"]},
                           {"metrics", {{"model", dj["metrics"]["model"]}, {"exact", dj["metrics"]["exact"]}}},
                           {"exact_direct_sum_check", dj["metrics"]["exact_direct_sum_check"]},
                           {"fabrication_errors", dj["fabrication_errors"]},
                           {"views", views_json},
                           {"warnings", dj["warnings"]},
                           {"timings_s", dj["timings_s"]}});
        // What the entry's own design.json says of its reach: the trade and the bounds.
        for (const char* key : {"brightness_trade", "optimal_colour_bound", "cone_bound", "mixture_bound"})
            if (dj.contains(key)) entries.back()[key] = dj[key];
        // The plate's own list names the entry, so that a dim or broken entry is said where the
        // plate's reader looks (its stderr, report and Python warnings read design.json's list).
        for (const auto& w : dj["warnings"])
            plate_warnings.push_back("palette entry " + o.palette[e].text + ": " + w.get<std::string>());
        r.tiles[e] = std::move(d);
    }

    // The plate: every pixel its entry's tile, in the plate's own texel phase.
    const auto assemble_start = Clock::now();
    const std::size_t rows = static_cast<std::size_t>(r.rows), cols = static_cast<std::size_t>(r.cols);
    r.heights_um = allocating("the plate's heights", 8.0 * static_cast<double>(rows * cols),
                              [&] { return std::vector<double>(rows * cols); });
    const int pt = p.pixel_texels;
#pragma omp parallel for schedule(static)
    for (std::ptrdiff_t I = 0; I < static_cast<std::ptrdiff_t>(rows); ++I) {
        const std::size_t pr = static_cast<std::size_t>(I / pt);
        const std::size_t ti = static_cast<std::size_t>(I % N);
        for (std::size_t J = 0; J < cols; ++J) {
            const std::size_t pc = J / static_cast<std::size_t>(pt);
            const int e = p.assignment[pr * static_cast<std::size_t>(o.picture.cols) + pc];
            r.heights_um[static_cast<std::size_t>(I) * cols + J] =
                r.tiles[static_cast<std::size_t>(e)].heights_um[ti * static_cast<std::size_t>(N) + J % static_cast<std::size_t>(N)];
        }
    }
    const double assemble_seconds = std::chrono::duration<double>(Clock::now() - assemble_start).count();

    // The picture and its appearance panels.
    r.picture_rows = o.picture.rows;
    r.picture_cols = o.picture.cols;
    const std::size_t P = p.assignment.size();
    r.picture_linear.resize(3 * P);
    for (std::size_t i = 0; i < P; ++i) {
        const auto c = pixel_linear(&o.picture.srgb8[3 * i]);
        for (std::size_t k = 0; k < 3; ++k) r.picture_linear[3 * i + k] = static_cast<float>(c[k]);
    }
    for (std::size_t v = 0; v < views.size(); ++v) {
        std::vector<std::array<double, 3>> rgb(K);
        for (std::size_t e = 0; e < K; ++e) rgb[e] = xyz_to_rgb(appearance_xyz[e][v]);
        std::vector<float> panel(3 * P);
        for (std::size_t i = 0; i < P; ++i)
            for (std::size_t k = 0; k < 3; ++k)
                panel[3 * i + k] = static_cast<float>(rgb[static_cast<std::size_t>(p.assignment[i])][k]);
        r.appearance.push_back(std::move(panel));
    }

    nlohmann::json j;
    j["kind"] = "design";
    j["version"] = k_version;
    nlohmann::json palette = nlohmann::json::array();
    for (const auto& e : o.palette) palette.push_back(e.text);
    j["target"] = {{"kind", "image"}, {"picture_file", o.picture.file}, {"picture_rows", o.picture.rows},
                   {"picture_cols", o.picture.cols}, {"palette", palette}, {"mapping", p.mapping},
                   {"view_cone", o.design.view_cone}};
    if (!o.palette.front().direction) j["target"]["view"] = views[0];
    j["plate"] = {{"rows", r.rows}, {"cols", r.cols}, {"texel_um", r.texel_um},
                  {"pixel_texels", p.pixel_texels}, {"plate_pixel_um", p.pixel_texels * r.texel_um},
                  {"tile_periods_per_pixel", p.pixel_texels / N},
                  {"size_um", {r.rows * r.texel_um, r.cols * r.texel_um}}};
    j["light"] = {{"omega_i", o.design.omega_i}, {"lambdas_um", lambdas}, {"spectral", o.design.spectral},
                  {"band_um", o.design.band_um}};
    j["constraints"] = {{"size", N}, {"texel_um", o.design.texel_um}, {"height_range_um", o.design.height_range_um},
                        {"levels", o.design.levels},
                        {"fabrication_error", {{"scale", o.design.errors.scale}, {"blur_um", o.design.errors.blur_um}}}};
    if (o.design.min_feature_um != 0.0) j["constraints"]["min_feature_um"] = o.design.min_feature_um;
    j["levels_um"] = r.levels_um;
    j["seed"] = o.design.seed;
    j["options"] = {{"iterations", o.design.iterations}, {"refine_passes", o.design.refine_passes}};
    j["entries"] = entries;
    j["warnings"] = plate_warnings;
    j["appearance_note"] =
        "each entry's tile under exact scalar diffraction (its periodic orders into the view cone); a region of "
        "finite size also spreads each order by about lambda / its width";
    j["estimated_bytes"] = p.estimated_bytes;
    j["notes"] = p.notes;
    j["timings_s"] = {{"assemble", assemble_seconds},
                      {"total", std::chrono::duration<double>(Clock::now() - start).count()}};
    r.metrics_json = j.dump(2);
    return r;
}

namespace {

// A panel of the picture's size scaled by an integer factor up (to at least 128 pixels a side)
// or a stride down (to at most 1024).
RgbImage scaled_panel(const std::vector<float>& data, int rows, int cols, double gain) {
    const int up = std::max(1, 128 / std::max(rows, cols));
    const int down = std::max(1, (std::max(rows, cols) + 1023) / 1024);
    RgbImage im;
    im.rows = rows * up / down;
    im.cols = cols * up / down;
    im.data.assign(static_cast<std::size_t>(im.rows) * static_cast<std::size_t>(im.cols) * 3, 0.0f);
    for (int i = 0; i < im.rows; ++i)
        for (int j = 0; j < im.cols; ++j) {
            const std::size_t si = static_cast<std::size_t>(std::min(rows - 1, i * down / up));
            const std::size_t sj = static_cast<std::size_t>(std::min(cols - 1, j * down / up));
            for (std::size_t k = 0; k < 3; ++k)
                im.data[(static_cast<std::size_t>(i) * static_cast<std::size_t>(im.cols) + static_cast<std::size_t>(j)) * 3 + k] =
                    static_cast<float>(gain * static_cast<double>(data[(si * static_cast<std::size_t>(cols) + sj) * 3 + k]));
        }
    return im;
}

RgbImage side_by_side(const std::vector<RgbImage>& panels, int gap) {
    RgbImage out;
    out.rows = panels.front().rows;
    for (const auto& p : panels) out.cols += p.cols;
    out.cols += gap * static_cast<int>(panels.size() - 1);
    out.data.assign(static_cast<std::size_t>(out.rows) * static_cast<std::size_t>(out.cols) * 3, 0.2f);
    int offset = 0;
    for (const auto& p : panels) {
        for (int i = 0; i < p.rows; ++i)
            for (int j = 0; j < p.cols; ++j)
                for (std::size_t k = 0; k < 3; ++k)
                    out.data[(static_cast<std::size_t>(i) * static_cast<std::size_t>(out.cols) + static_cast<std::size_t>(offset + j)) * 3 + k] =
                        p.data[(static_cast<std::size_t>(i) * static_cast<std::size_t>(p.cols) + static_cast<std::size_t>(j)) * 3 + k];
        offset += p.cols + gap;
    }
    return out;
}

}  // namespace

void write_plate_directory(const std::string& dir, const PlateResult& r, bool force) {
    prepare_run_directory(RunKind::Design, dir, force);
    const std::filesystem::path d(dir);
    {
        std::vector<double> values(r.heights_um.size());
        for (std::size_t t = 0; t < values.size(); ++t) values[t] = r.heights_um[t] / r.texel_um;
        const Heightfield hf(r.rows, r.cols, std::move(values), r.texel_um, 1.0);
        write_heightfield_exr((d / "heights.exr").string(), hf, "wavebrdf design (plate)");
    }
    // A grayscale plate (--min-feature-um) is written for grayscale lithography: no etch masks.
    const bool grayscale = nlohmann::json::parse(r.metrics_json)["constraints"].value("min_feature_um", 0.0) > 0.0;
    const FabricationFiles files = write_fabrication_exports(dir, r.heights_um, r.rows, r.cols, r.texel_um,
                                                             r.levels_um.back(),
                                                             grayscale ? 0 : static_cast<int>(r.levels_um.size()), 1e9);
    // plate.exr: the appearance panels side by side, linear (fractions of the incident light);
    // plate.png: the picture, then each panel scaled so that its brightest channel is 1.
    std::vector<RgbImage> linear, shown;
    shown.push_back(scaled_panel(r.picture_linear, r.picture_rows, r.picture_cols, 1.0));
    for (const auto& panel : r.appearance) {
        float peak = 0.0f;
        for (float x : panel) peak = std::max(peak, x);
        linear.push_back(scaled_panel(panel, r.picture_rows, r.picture_cols, 1.0));
        shown.push_back(scaled_panel(panel, r.picture_rows, r.picture_cols, peak > 0.0f ? 1.0 / static_cast<double>(peak) : 0.0));
    }
    write_rgb_exr((d / "plate.exr").string(), side_by_side(linear, 0));
    write_rgb_png((d / "plate.png").string(), side_by_side(shown, 8));
    nlohmann::json j = nlohmann::json::parse(r.metrics_json);
    nlohmann::json fabrication = detail::fabrication_files_json(files);
    fabrication["x3p_note"] = files.x3p_note;
    fabrication["plate_png"] = "plate.png";
    fabrication["plate_exr"] = "plate.exr";
    fabrication["views"] = r.view_names;
    j["fabrication_files"] = fabrication;
    write_text_atomically((d / "design.json").string(), j.dump(2) + "\n");
}

}  // namespace wavebrdf
