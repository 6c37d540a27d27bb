#include "wavebrdf/preview.h"

#include <png.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <cstdlib>
#include <stdexcept>
#include <utility>

#include "core/srgb.h"
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
    {'m', {"...", "###", "###", "#.#", "#.#"}}, {'w', {"...", "#.#", "#.#", "###", "###"}},
    {'x', {"...", "#.#", ".#.", "#.#", "#.#"}}, {'y', {"...", "#.#", "###", "..#", "##."}},
    {',', {"...", "...", "...", ".#.", "#.."}},
};

const Glyph* glyph(char c) {
    for (const Glyph& g : k_font)
        if (g.c == c) return &g;
    return nullptr;
}

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
        double x = detail::srgb_decode(t);
        if (reinhard) {
            if (k == 4) continue;
            x = x / (1.0 - x);
        }
        ticks.emplace_back(t, format_g(x * std::exp2(-exposure_stops), 2));
    }
    return ticks;
}

// A picture's pixel (row i, column j).
std::uint8_t* at(Preview8& p, int i, int j) {
    return &p.rgb[(static_cast<std::size_t>(i) * static_cast<std::size_t>(p.cols) + static_cast<std::size_t>(j)) * 3u];
}

void fill(Preview8& p, int i0, int i1, int j0, int j1, std::uint8_t grey) {
    for (int i = std::max(i0, 0); i <= std::min(i1, p.rows - 1); ++i)
        for (int j = std::max(j0, 0); j <= std::min(j1, p.cols - 1); ++j) {
            std::uint8_t* px = at(p, i, j);
            px[0] = px[1] = px[2] = grey;
        }
}

// `picture` copied into a canvas `top` rows and `left` columns in, of rows × cols, black.
Preview8 placed(const Preview8& picture, int rows, int cols, int top, int left) {
    Preview8 out;
    out.rows = rows;
    out.cols = cols;
    out.rgb.assign(static_cast<std::size_t>(rows) * static_cast<std::size_t>(cols) * 3u, 0);
    for (int i = 0; i < picture.rows; ++i)
        std::memcpy(at(out, top + i, left), &picture.rgb[static_cast<std::size_t>(i) * std::size_t(picture.cols) * 3u],
                    static_cast<std::size_t>(picture.cols) * 3u);
    out.image_top = picture.image_top + top;
    out.image_left = picture.image_left + left;
    out.image_rows = picture.image_rows;
    out.image_cols = picture.image_cols;
    out.magnify = picture.magnify;
    return out;
}

// Tick values of a 1-2-5 step for [lo, hi]: three to about eight of them.
std::vector<double> axis_ticks(double lo, double hi) {
    const double raw = (hi - lo) / 4.0;
    const double magnitude = std::pow(10.0, std::floor(std::log10(raw)));
    double step = 10.0 * magnitude;
    for (double m : {1.0, 2.0, 5.0})
        if (m * magnitude >= raw * 0.999) {
            step = m * magnitude;
            break;
        }
    std::vector<double> ticks;
    for (long long k = static_cast<long long>(std::ceil(lo / step - 1e-9));
         k <= static_cast<long long>(std::floor(hi / step + 1e-9)); ++k)
        ticks.push_back(double(k) * step);
    return ticks;
}

// A frame around `picture` with ω ticks and labels: ω_x along the rows (left, "wx"), the rows'
// edges at wx0 (top) and wx1 (bottom); ω_y along the columns (below, "wy"), wy0 (left) to wy1.
Preview8 with_axes(const Preview8& picture, double wx0, double wx1, double wy0, double wy1) {
    const int s = std::clamp(std::max(picture.rows, picture.cols) / 128, 1, 4);
    const int glyph = 5 * s, tick = 2 * s, gap = 2 * s;
    const std::vector<double> x_ticks = axis_ticks(wx0, wx1), y_ticks = axis_ticks(wy0, wy1);
    const auto label = [](double v) { return format_g(std::abs(v) < 1e-12 ? 0.0 : v, 3); };
    int x_label_width = 0;
    for (double v : x_ticks) x_label_width = std::max(x_label_width, text_width(label(v), s));
    int last_y_label = y_ticks.empty() ? 0 : text_width(label(y_ticks.back()), s);
    const int title_x = text_width("wx", s);
    const int left = title_x + gap + x_label_width + gap + tick + 1;
    const int top = glyph / 2 + s;
    const int bottom = 1 + tick + gap + glyph + gap + glyph + s;
    const int right = std::max(last_y_label / 2, s) + s;
    Preview8 out = placed(picture, top + picture.rows + bottom, left + picture.cols + right, top, left);
    const std::uint8_t line = 200;
    // The frame, one pixel outside the picture.
    fill(out, top - 1, top - 1, left - 1, left + picture.cols, line);
    fill(out, top + picture.rows, top + picture.rows, left - 1, left + picture.cols, line);
    fill(out, top - 1, top + picture.rows, left - 1, left - 1, line);
    fill(out, top - 1, top + picture.rows, left + picture.cols, left + picture.cols, line);
    const auto position = [](double v, double lo, double hi, int size) {
        return std::clamp(static_cast<int>(std::floor((v - lo) / (hi - lo) * size)), 0, size - 1);
    };
    for (double v : x_ticks) {
        const int row = top + position(v, wx0, wx1, picture.rows);
        fill(out, row, row, left - 1 - tick, left - 2, line);
        const std::string text = label(v);
        draw_text(out, std::clamp(row - glyph / 2, 0, out.rows - glyph), left - 1 - tick - gap - text_width(text, s),
                  text, s, 255);
    }
    for (double v : y_ticks) {
        const int col = left + position(v, wy0, wy1, picture.cols);
        fill(out, top + picture.rows + 1, top + picture.rows + tick, col, col, line);
        const std::string text = label(v);
        draw_text(out, top + picture.rows + 1 + tick + gap,
                  std::clamp(col - text_width(text, s) / 2, 0, out.cols - text_width(text, s)), text, s, 255);
    }
    draw_text(out, top + picture.rows / 2 - glyph / 2, 0, "wx", s, 255);
    draw_text(out, top + picture.rows + 1 + tick + gap + glyph + gap, left + picture.cols / 2 - text_width("wy", s) / 2,
              "wy", s, 255);
    return out;
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

OmegaWindow parse_omega_window(const std::string& text, const std::string& name) {
    const auto bad = [&] {
        return std::invalid_argument(name + " '" + text +
                                     "' is invalid; expected x0,x1,y0,y1: four numbers, the window's omega_x and "
                                     "omega_y ranges in [-1, 1] (e.g. -0.2,0.2,-0.2,0.2)");
    };
    double v[4];
    std::size_t at = 0;
    for (int k = 0; k < 4; ++k) {
        const std::size_t end = k < 3 ? text.find(',', at) : text.size();
        if (end == std::string::npos) throw bad();
        std::string part = text.substr(at, end - at);
        while (!part.empty() && part.front() == ' ') part.erase(part.begin());
        while (!part.empty() && part.back() == ' ') part.pop_back();
        if (part.empty()) throw bad();
        char* stop = nullptr;
        v[k] = std::strtod(part.c_str(), &stop);
        if (stop != part.c_str() + part.size() || !std::isfinite(v[k])) throw bad();
        at = end + 1;
    }
    const char* names[4] = {"x0", "x1", "y0", "y1"};
    for (int k = 0; k < 4; ++k)
        if (v[k] < -1.0 || v[k] > 1.0)
            throw std::domain_error(name + " " + text + ": " + names[k] + " = " + format_shortest(v[k]) +
                                    " is outside [-1, 1]; expected projected directions");
    if (!(v[0] < v[1]) || !(v[2] < v[3]))
        throw std::domain_error(name + " " + text + ": " + (v[0] < v[1] ? "y0 " : "x0 ") +
                                format_shortest(v[0] < v[1] ? v[2] : v[0]) + " is not below " +
                                (v[0] < v[1] ? "y1 " : "x1 ") + format_shortest(v[0] < v[1] ? v[3] : v[1]) +
                                "; expected x0 < x1 and y0 < y1");
    return {v[0], v[1], v[2], v[3]};
}

PixelBox window_pixels(const OmegaWindow& w, int n) {
    // Pixel i's centre, exactly as the renderer places it.
    const auto centre = [n](int i) { return (i + 0.5) / n * 2.0 - 1.0; };
    const auto range = [&](double lo, double hi, int& first, int& last) {
        first = std::clamp(static_cast<int>(std::floor((lo + 1.0) * 0.5 * n - 0.5)), 0, n - 1);
        while (first < n && centre(first) < lo) ++first;
        while (first > 0 && centre(first - 1) >= lo) --first;
        last = std::clamp(static_cast<int>(std::ceil((hi + 1.0) * 0.5 * n - 0.5)), 0, n - 1);
        while (last >= 0 && centre(last) > hi) --last;
        while (last < n - 1 && centre(last + 1) <= hi) ++last;
    };
    PixelBox box;
    range(w.x0, w.x1, box.first_row, box.last_row);
    range(w.y0, w.y1, box.first_col, box.last_col);
    if (box.first_row > box.last_row || box.first_col > box.last_col)
        throw std::invalid_argument(
            "window " + format_shortest(w.x0) + "," + format_shortest(w.x1) + "," + format_shortest(w.y0) + "," +
            format_shortest(w.y1) + " holds no pixel centre of the " + std::to_string(n) + "x" + std::to_string(n) +
            " slice (pixels are " + format_shortest(2.0 / n) + " wide in omega); expected a wider window");
    return box;
}

Preview8 make_slice_preview(const RgbImage& image, const PreviewOptions& options) {
    validate_preview_options(options);
    check_side(image.rows, "rows");
    check_side(image.cols, "columns");
    const std::size_t count = static_cast<std::size_t>(image.rows) * static_cast<std::size_t>(image.cols);
    if (image.data.size() != count * 3u)
        throw std::invalid_argument("preview image holds " + std::to_string(image.data.size()) +
                                    " values; expected rows * cols * 3 = " + std::to_string(count * 3u));
    if (options.has_window || options.axes) {
        // The picture of the window's pixels alone, scaled up, then the axes and the bar around it.
        if (image.rows != image.cols)
            throw std::invalid_argument("preview axes and windows need a square slice; got " +
                                        std::to_string(image.rows) + "x" + std::to_string(image.cols));
        const int n = image.rows;
        const PixelBox box = options.has_window ? window_pixels(options.window, n) : PixelBox{0, n - 1, 0, n - 1};
        RgbImage crop;
        crop.rows = box.last_row - box.first_row + 1;
        crop.cols = box.last_col - box.first_col + 1;
        crop.data.reserve(static_cast<std::size_t>(crop.rows) * std::size_t(crop.cols) * 3u);
        for (int i = box.first_row; i <= box.last_row; ++i)
            crop.data.insert(crop.data.end(), image.data.begin() + (std::ptrdiff_t(i) * n + box.first_col) * 3,
                             image.data.begin() + (std::ptrdiff_t(i) * n + box.last_col + 1) * 3);
        PreviewOptions plain = options;
        plain.has_window = plain.axes = plain.colour_bar = false;
        const Preview8 small = make_slice_preview(crop, plain);
        const int k = options.has_window ? std::clamp(256 / std::max(crop.rows, crop.cols), 1, 16) : 1;
        Preview8 picture;
        picture.rows = crop.rows * k;
        picture.cols = crop.cols * k;
        picture.rgb.resize(static_cast<std::size_t>(picture.rows) * std::size_t(picture.cols) * 3u);
        for (int i = 0; i < picture.rows; ++i)
            for (int j = 0; j < picture.cols; ++j)
                std::memcpy(at(picture, i, j),
                            &small.rgb[(std::size_t(i / k) * std::size_t(crop.cols) + std::size_t(j / k)) * 3u], 3);
        picture.image_rows = picture.rows;
        picture.image_cols = picture.cols;
        picture.magnify = k;
        if (options.axes) {
            const auto edge = [n](int i) { return double(i) / n * 2.0 - 1.0; };
            picture = with_axes(picture, edge(box.first_row), edge(box.last_row + 1), edge(box.first_col),
                                edge(box.last_col + 1));
        }
        if (!options.colour_bar) return picture;
        double peak = 0.0;
        for (std::size_t p = 0; p < crop.data.size() / 3; ++p) {
            const double r = static_cast<double>(crop.data[3 * p]), g = static_cast<double>(crop.data[3 * p + 1]),
                         b = static_cast<double>(crop.data[3 * p + 2]);
            const double v = r == g && g == b ? r : 0.2126 * r + 0.7152 * g + 0.0722 * b;
            if (std::isfinite(v)) peak = std::max(peak, v);
        }
        std::vector<Tick> ticks;
        if (options.scale == PreviewScale::Linear)
            ticks = linear_ticks(options.exposure_stops, options.reinhard);
        else if (peak > 0.0)
            ticks = log_ticks(peak, options.log_decades);
        else
            ticks = {{0.0, "0"}};
        Preview8 out = with_colour_bar(picture, ticks, options.unit, options.false_colour);
        out.image_top = picture.image_top;
        out.image_left = picture.image_left;
        out.image_rows = picture.image_rows;
        out.image_cols = picture.image_cols;
        out.magnify = picture.magnify;
        return out;
    }
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
    out.rows = out.image_rows = image.rows;
    out.cols = out.image_cols = image.cols;
    out.rgb.assign(count * 3u, 0);
    const double scale = std::exp2(options.exposure_stops);
    // write_rgb_png's mapping of one linear value to a displayed level.
    const auto linear = [&](double v) {
        double x = std::isfinite(v) ? std::max(v * scale, 0.0) : 0.0;
        if (options.reinhard) x = std::isinf(x) ? 1.0 : x / (1.0 + x);
        return detail::srgb_encode(std::min(x, 1.0));
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

Preview8 make_table_preview(const RgbImage& mosaic, int n, const std::vector<double>& light_x,
                            const std::vector<double>& light_y, double exposure_stops) {
    const int rows = static_cast<int>(light_x.size()), cols = static_cast<int>(light_y.size());
    if (n < 1 || rows < 1 || cols < 1 || mosaic.rows != rows * n || mosaic.cols != cols * n ||
        mosaic.data.size() != static_cast<std::size_t>(mosaic.rows) * std::size_t(mosaic.cols) * 3u)
        throw std::invalid_argument("table preview: a mosaic of " + std::to_string(mosaic.rows) + "x" +
                                    std::to_string(mosaic.cols) + " pixels does not hold " + std::to_string(rows) +
                                    "x" + std::to_string(cols) + " tiles of " + std::to_string(n) + "x" +
                                    std::to_string(n));
    check_side(mosaic.rows + rows + 1, "rows");
    check_side(mosaic.cols + cols + 1, "columns");
    const int s = std::clamp(n / 32, 1, 3);
    const int glyph = 5 * s, gap = 2 * s;
    const auto label = [](double v) { return format_g(std::abs(v) < 1e-12 ? 0.0 : v, 2); };
    int row_label_width = text_width("wx", s);
    for (double v : light_x) row_label_width = std::max(row_label_width, text_width(label(v), s));
    const int left = row_label_width + 2 * gap, top = 2 * glyph + 3 * gap;
    Preview8 out;
    out.rows = top + rows * (n + 1) + 1;
    out.cols = left + cols * (n + 1) + 1;
    out.rgb.assign(static_cast<std::size_t>(out.rows) * std::size_t(out.cols) * 3u, 0);
    out.image_top = top + 1;
    out.image_left = left + 1;
    out.image_rows = rows * (n + 1) - 1;
    out.image_cols = cols * (n + 1) - 1;
    const std::uint8_t line = 96;
    for (int a = 0; a <= rows; ++a) fill(out, top + a * (n + 1), top + a * (n + 1), left, out.cols - 1, line);
    for (int b = 0; b <= cols; ++b) fill(out, top, out.rows - 1, left + b * (n + 1), left + b * (n + 1), line);
    // write_rgb_png's mapping: value · 2^exposure, Reinhard, the sRGB curve.
    const double scale = std::exp2(exposure_stops);
    for (int i = 0; i < mosaic.rows; ++i)
        for (int j = 0; j < mosaic.cols; ++j) {
            std::uint8_t* px = at(out, top + 1 + i + i / n, left + 1 + j + j / n);
            for (std::size_t c = 0; c < 3; ++c) {
                double x = double(mosaic.data[(std::size_t(i) * std::size_t(mosaic.cols) + std::size_t(j)) * 3u + c]);
                x = std::isfinite(x) ? std::max(x * scale, 0.0) : 0.0;
                x = std::isinf(x) ? 1.0 : x / (1.0 + x);
                px[c] = to_byte(detail::srgb_encode(std::min(x, 1.0)));
            }
        }
    // Light labels: ω_i,x left of each row of tiles, ω_i,y above each column; the axes' names
    // in the corner ("wy" over the column labels' line, "wx" over the row labels).
    for (int a = 0; a < rows; ++a) {
        const std::string text = label(light_x[std::size_t(a)]);
        draw_text(out, top + 1 + a * (n + 1) + n / 2 - glyph / 2, left - gap - text_width(text, s), text, s, 255);
    }
    for (int b = 0; b < cols; ++b) {
        const std::string text = label(light_y[std::size_t(b)]);
        if (text_width(text, s) > n) continue;
        draw_text(out, top - gap - glyph, left + 1 + b * (n + 1) + (n - text_width(text, s)) / 2, text, s, 255);
    }
    draw_text(out, top - gap - glyph, left - gap - text_width("wx", s), "wx", s, 255);
    draw_text(out, gap, left + 1, "wy", s, 255);
    return out;
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
