#include "wavebrdf/preview.h"

#include <png.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <stdexcept>
#include <utility>

#include "wavebrdf/text.h"

namespace wavebrdf {

namespace {

// matplotlib's viridis, the published table (source and licence in the file).
constexpr double k_viridis[256][3] = {
#include "viridis_table.inc"
};

// The 3×5 font: five rows of three pixels per glyph, '#' set.
struct Glyph {
    char c;
    const char* rows[5];
};
constexpr Glyph k_font[] = {
    {'0', {"###", "#.#", "#.#", "#.#", "###"}}, {'1', {".#.", "##.", ".#.", ".#.", "###"}},
    {'2', {"###", "..#", "###", "#..", "###"}}, {'3', {"###", "..#", ".##", "..#", "###"}},
    {'4', {"#.#", "#.#", "###", "..#", "..#"}}, {'5', {"###", "#..", "###", "..#", "###"}},
    {'6', {"###", "#..", "###", "#.#", "###"}}, {'7', {"###", "..#", ".#.", ".#.", ".#."}},
    {'8', {"###", "#.#", "###", "#.#", "###"}}, {'9', {"###", "#.#", "###", "..#", "###"}},
    {'.', {"...", "...", "...", "...", ".#."}}, {'-', {"...", "...", "###", "...", "..."}},
    {'+', {"...", ".#.", "###", ".#.", "..."}}, {'e', {".#.", "#.#", "###", "#..", ".##"}},
    {'/', {"..#", "..#", ".#.", "#..", "#.."}}, {'s', {".##", "#..", ".#.", "..#", "##."}},
    {'r', {"...", "#.#", "##.", "#..", "#.."}}, {'u', {"...", "#.#", "#.#", "#.#", "###"}},
    {'m', {"...", "###", "###", "#.#", "#.#"}},
};

const Glyph* glyph(char c) {
    for (const Glyph& g : k_font)
        if (g.c == c) return &g;
    return nullptr;
}

// sRGB transfer curve (IEC 61966-2-1) on [0, 1] and its inverse (as io.cpp's write_rgb_png).
double srgb_encode(double x) { return x <= 0.0031308 ? 12.92 * x : 1.055 * std::pow(x, 1.0 / 2.4) - 0.055; }
double srgb_decode(double y) { return y <= 0.04045 ? y / 12.92 : std::pow((y + 0.055) / 1.055, 2.4); }

std::uint8_t to_byte(double t) { return static_cast<std::uint8_t>(std::lround(std::clamp(t, 0.0, 1.0) * 255.0)); }

// A level t in [0, 1] as a pixel: grey, or viridis.
void put_level(std::uint8_t* pixel, double t, bool false_colour) {
    if (false_colour) {
        const std::array<double, 3> c = viridis(t);
        for (int k = 0; k < 3; ++k) pixel[k] = to_byte(c[static_cast<std::size_t>(k)]);
    } else {
        pixel[0] = pixel[1] = pixel[2] = to_byte(t);
    }
}

// "%.{digits}g" (digits, '.', '-', 'e', '+'), with "-0" as "0".
std::string format_g(double value, int digits) {
    char text[32];
    std::snprintf(text, sizeof text, "%.*g", digits, value == 0.0 ? 0.0 : value);
    return text;
}

// A tick of the colour bar: its level and label.
using Tick = std::pair<double, std::string>;

// Copies `picture` into a wider canvas with a colour bar right of it: levels 0 (bottom) … 1
// (top) drawn as `false_colour` says, a tick mark and label per tick, `unit` above the bar.
Preview8 with_colour_bar(const Preview8& picture, const std::vector<Tick>& ticks, const std::string& unit,
                         bool false_colour) {
    const int s = std::clamp(picture.rows / 128, 1, 4);  // font scale: readable at 256² and 1024²
    const int gap = 3 * s, bar_width = 5 * s, tick_length = 2 * s, glyph_height = 5 * s;
    const int margin = glyph_height / 2 + s;  // half a label above the top tick and below the bottom one
    const int caption = unit.empty() ? 0 : glyph_height + 2 * s;
    int label_width = 0;
    for (const Tick& t : ticks) label_width = std::max(label_width, text_width(t.second, s));
    const int min_bar = static_cast<int>(ticks.size() + 1) * (glyph_height + 2 * s);
    Preview8 out;
    out.rows = std::max(picture.rows, caption + 2 * margin + min_bar);
    const int bar_left = picture.cols + gap;
    const int label_left = bar_left + bar_width + tick_length + 3 * s;  // a gap: a tick is no minus sign
    out.cols = std::max(label_left + label_width, bar_left + text_width(unit, s)) + 2 * s;
    out.rgb.assign(static_cast<std::size_t>(out.rows) * static_cast<std::size_t>(out.cols) * 3u, 0);
    for (int i = 0; i < picture.rows; ++i)
        std::memcpy(&out.rgb[(static_cast<std::size_t>(i) * static_cast<std::size_t>(out.cols)) * 3u],
                    &picture.rgb[(static_cast<std::size_t>(i) * static_cast<std::size_t>(picture.cols)) * 3u],
                    static_cast<std::size_t>(picture.cols) * 3u);
    out.bar_top = caption + margin;
    out.bar_bottom = out.rows - 1 - margin;
    out.bar_left = bar_left;
    out.bar_right = bar_left + bar_width - 1;
    const int span = std::max(out.bar_bottom - out.bar_top, 1);
    for (int i = out.bar_top; i <= out.bar_bottom; ++i) {
        const double t = double(out.bar_bottom - i) / double(span);
        for (int j = out.bar_left; j <= out.bar_right; ++j)
            put_level(&out.rgb[(static_cast<std::size_t>(i) * static_cast<std::size_t>(out.cols) +
                                static_cast<std::size_t>(j)) *
                               3u],
                      t, false_colour);
    }
    if (!unit.empty()) draw_text(out, s, bar_left, unit, s, 255);
    for (const Tick& t : ticks) {
        const int row = out.bar_bottom - static_cast<int>(std::lround(std::clamp(t.first, 0.0, 1.0) * span));
        for (int i = row - (s - 1) / 2; i <= row + s / 2; ++i)
            for (int j = out.bar_right + 1; j <= out.bar_right + tick_length; ++j)
                if (i >= 0 && i < out.rows)
                    for (int c = 0; c < 3; ++c)
                        out.rgb[(static_cast<std::size_t>(i) * static_cast<std::size_t>(out.cols) +
                                 static_cast<std::size_t>(j)) *
                                    3u +
                                static_cast<std::size_t>(c)] = 255;
        draw_text(out, std::clamp(row - glyph_height / 2, 0, out.rows - glyph_height), label_left, t.second, s, 255);
    }
    return out;
}

// Ticks of a log bar from floor = peak·10^−decades to peak: every power of ten in between (at
// most 8, thinned evenly), or both ends when fewer than two powers fall inside.
std::vector<Tick> log_ticks(double peak, double decades) {
    std::vector<Tick> ticks;
    const double top = std::log10(peak), bottom = top - decades;
    const int first = static_cast<int>(std::ceil(bottom - 1e-9)), last = static_cast<int>(std::floor(top + 1e-9));
    if (last - first + 1 >= 2) {
        const int step = (last - first) / 8 + 1;
        for (int m = last; m >= first; m -= step)
            ticks.emplace_back(std::clamp(1.0 + (m - top) / decades, 0.0, 1.0),
                               m == 0 ? std::string("1") : "1e" + std::to_string(m));
    } else {
        ticks.emplace_back(1.0, format_g(peak, 2));
        ticks.emplace_back(0.0, format_g(std::pow(10.0, bottom), 2));
    }
    return ticks;
}

// Ticks of a linear bar at levels 0, ¼, ½, ¾, 1 (the displayed, sRGB-encoded level); the
// value of each is the mapping inverted (Reinhard's top, infinity, has none).
std::vector<Tick> linear_ticks(double exposure_stops, bool reinhard) {
    std::vector<Tick> ticks;
    for (int k = 4; k >= 0; --k) {
        const double t = k / 4.0;
        double x = srgb_decode(t);
        if (reinhard) {
            if (k == 4) continue;
            x = x / (1.0 - x);
        }
        ticks.emplace_back(t, format_g(x * std::exp2(-exposure_stops), 2));
    }
    return ticks;
}

void check_side(int side, const char* what) {
    if (side < 1 || side > 16384)
        throw std::invalid_argument(std::string("preview ") + what + " " + std::to_string(side) +
                                    " is out of range; expected 1 to 16384");
}

}  // namespace

void validate_preview_options(const PreviewOptions& options) {
    if (!(options.log_decades > 0.0 && options.log_decades <= 30.0))
        throw std::domain_error("log decades " + format_shortest(options.log_decades) +
                                " is out of range; expected more than 0 and at most 30");
    if (!std::isfinite(options.exposure_stops))
        throw std::domain_error("exposure " + format_shortest(options.exposure_stops) +
                                " is invalid; expected a finite number of stops");
}

double log_level(double value, double peak, double decades) {
    if (!(value > 0.0) || !std::isfinite(value) || !(peak > 0.0) || !std::isfinite(peak)) return 0.0;
    return std::clamp(1.0 + std::log10(value / peak) / decades, 0.0, 1.0);
}

std::array<double, 3> viridis(double t) {
    const double x = (std::isnan(t) ? 0.0 : std::clamp(t, 0.0, 1.0)) * 255.0;
    const int k = std::min(static_cast<int>(x), 254);
    const double f = x - k;
    std::array<double, 3> c{};
    for (std::size_t i = 0; i < 3; ++i) c[i] = (1.0 - f) * k_viridis[k][i] + f * k_viridis[k + 1][i];
    return c;
}

int text_width(const std::string& text, int scale) {
    return text.empty() ? 0 : static_cast<int>(text.size()) * 4 * scale - scale;
}

void draw_text(Preview8& picture, int row, int col, const std::string& text, int scale, std::uint8_t grey) {
    scale = std::clamp(scale, 1, 16);
    for (std::size_t n = 0; n < text.size(); ++n) {
        const Glyph* g = glyph(text[n]);
        if (g == nullptr) continue;
        for (int gi = 0; gi < 5; ++gi)
            for (int gj = 0; gj < 3; ++gj) {
                if (g->rows[gi][gj] != '#') continue;
                for (int di = 0; di < scale; ++di)
                    for (int dj = 0; dj < scale; ++dj) {
                        const long long i = row + gi * scale + di;
                        const long long j = col + (static_cast<long long>(n) * 4 + gj) * scale + dj;
                        if (i < 0 || j < 0 || i >= picture.rows || j >= picture.cols) continue;
                        for (int c = 0; c < 3; ++c)
                            picture.rgb[static_cast<std::size_t>((i * picture.cols + j) * 3 + c)] = grey;
                    }
            }
    }
}

Preview8 make_slice_preview(const RgbImage& image, const PreviewOptions& options) {
    validate_preview_options(options);
    check_side(image.rows, "rows");
    check_side(image.cols, "columns");
    const std::size_t count = static_cast<std::size_t>(image.rows) * static_cast<std::size_t>(image.cols);
    if (image.data.size() != count * 3u)
        throw std::invalid_argument("preview image holds " + std::to_string(image.data.size()) +
                                    " values; expected rows * cols * 3 = " + std::to_string(count * 3u));
    // The value each pixel's level comes from: a grey pixel's own value, else the luminance
    // (computed twice rather than stored: an 8192² slice would need 512 MiB more).
    const auto value = [&](std::size_t p) {
        const double r = double(image.data[3 * p]), g = double(image.data[3 * p + 1]),
                     b = double(image.data[3 * p + 2]);
        return r == g && g == b ? r : 0.2126 * r + 0.7152 * g + 0.0722 * b;
    };
    double peak = 0.0;
    for (std::size_t p = 0; p < count; ++p)
        if (std::isfinite(value(p))) peak = std::max(peak, value(p));
    Preview8 out;
    out.rows = image.rows;
    out.cols = image.cols;
    out.rgb.assign(count * 3u, 0);
    const double scale = std::exp2(options.exposure_stops);
    // write_rgb_png's mapping of one linear value to a displayed level.
    const auto linear = [&](double v) {
        double x = std::isfinite(v) ? std::max(v * scale, 0.0) : 0.0;
        if (options.reinhard) x = std::isinf(x) ? 1.0 : x / (1.0 + x);
        return srgb_encode(std::min(x, 1.0));
    };
    for (std::size_t p = 0; p < count; ++p) {
        std::uint8_t* pixel = &out.rgb[3 * p];
        if (options.scale == PreviewScale::Linear) {
            if (options.false_colour) {
                put_level(pixel, linear(value(p)), true);
            } else {
                for (std::size_t c = 0; c < 3; ++c) pixel[c] = to_byte(linear(double(image.data[3 * p + c])));
            }
            continue;
        }
        const double t = log_level(value(p), peak, options.log_decades);
        if (options.false_colour) {
            put_level(pixel, t, true);
            continue;
        }
        // Keep the hue: the largest channel shows the level.
        const double r = double(image.data[3 * p]), g = double(image.data[3 * p + 1]),
                     b = double(image.data[3 * p + 2]);
        const double m = std::max({r, g, b});
        if (!(m > 0.0) || !std::isfinite(m) || !std::isfinite(r + g + b)) continue;
        for (std::size_t c = 0; c < 3; ++c) pixel[c] = to_byte(t * std::max(double(image.data[3 * p + c]), 0.0) / m);
    }
    if (!options.colour_bar) return out;
    std::vector<Tick> ticks;
    if (options.scale == PreviewScale::Linear)
        ticks = linear_ticks(options.exposure_stops, options.reinhard);
    else if (peak > 0.0)
        ticks = log_ticks(peak, options.log_decades);
    else
        ticks = {{0.0, "0"}};  // an all-black slice: nothing to scale
    return with_colour_bar(out, ticks, options.unit, options.false_colour);
}

Preview8 make_heightfield_preview(const Heightfield& heightfield, bool false_colour, bool colour_bar) {
    check_side(heightfield.rows(), "rows");
    check_side(heightfield.cols(), "columns");
    const std::vector<double>& values = heightfield.values();
    const auto [lo, hi] = std::minmax_element(values.begin(), values.end());
    const double min = *lo, range = *hi - *lo;
    Preview8 out;
    out.rows = heightfield.rows();
    out.cols = heightfield.cols();
    out.rgb.assign(values.size() * 3u, 0);
    for (std::size_t k = 0; k < values.size(); ++k)
        // A flat field has no range to stretch; mid grey says "constant" (write_heightfield_png).
        put_level(&out.rgb[3 * k], range > 0.0 ? (values[k] - min) / range : 128.0 / 255.0, false_colour);
    if (!colour_bar) return out;
    const double um = heightfield.vscale() * heightfield.texel_um();
    std::vector<Tick> ticks;
    if (range > 0.0) {
        for (int k = 4; k >= 0; --k) ticks.emplace_back(k / 4.0, format_g((min + range * k / 4.0) * um, 3));
    } else {
        ticks.emplace_back(128.0 / 255.0, format_g(min * um, 3));
    }
    return with_colour_bar(out, ticks, "um", false_colour);
}

void write_preview_png(const std::string& path, const Preview8& picture) {
    check_side(picture.rows, "rows");
    check_side(picture.cols, "columns");
    if (picture.rgb.size() != static_cast<std::size_t>(picture.rows) * static_cast<std::size_t>(picture.cols) * 3u)
        throw std::invalid_argument("preview holds " + std::to_string(picture.rgb.size()) +
                                    " bytes; expected rows * cols * 3");
    write_file_atomically(path, [&](const std::string& tmp) {
        // libpng's simplified API reports errors through its return value, not longjmp.
        png_image image;
        std::memset(&image, 0, sizeof image);
        image.version = PNG_IMAGE_VERSION;
        image.width = static_cast<png_uint_32>(picture.cols);
        image.height = static_cast<png_uint_32>(picture.rows);
        image.format = PNG_FORMAT_RGB;
        if (png_image_write_to_file(&image, tmp.c_str(), 0, picture.rgb.data(), 0, nullptr) == 0) {
            const std::string message = image.message;
            png_image_free(&image);
            throw std::runtime_error("libpng: " + message);
        }
    });
}

}  // namespace wavebrdf
