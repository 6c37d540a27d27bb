#pragma once
// Previews: 8-bit PNG pictures of slices and heightfields for a person to look at (the data
// are in the EXR). A slice spans many decades (the specular peak and the diffraction haze
// around it), so the default is a log scale: a linear map that shows the peak shows nothing
// else. Optional: a false-colour map of the luminance (viridis) and a colour bar with tick
// labels of the value scale (a built-in 3×5 pixel font), so a picture can be read without
// the file. write_rgb_png and write_heightfield_png (io.h) stay as they were.
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "wavebrdf/heightfield.h"
#include "wavebrdf/io.h"

namespace wavebrdf {

enum class PreviewScale {
    Log,     // grey level 1 + log10(value / peak) / log_decades, clamped to [0, 1]
    Linear,  // value · 2^exposure, optionally Reinhard x/(1+x), clamped, sRGB curve (write_rgb_png)
};

// A rectangle of projected outgoing directions: ω_x from x0 to x1, ω_y from y0 to y1, each
// −1 ≤ lower < upper ≤ 1. The whole slice is (−1, 1, −1, 1).
struct OmegaWindow {
    double x0 = -1.0, x1 = 1.0, y0 = -1.0, y1 = 1.0;
};

// "x0,x1,y0,y1" (four numbers, commas, blanks allowed around them). Throws
// std::invalid_argument "NAME 'TEXT' is invalid; expected x0,x1,y0,y1 ..." for text that is
// not four finite numbers, std::domain_error naming the bound for one outside [−1, 1] or a
// lower bound not below its upper one.
OmegaWindow parse_omega_window(const std::string& text, const std::string& name = "window");

// The pixels of an n × n slice inside `window`: rows first_row…last_row (pixel row i is
// ω_x = (i + ½)/n · 2 − 1) and columns first_col…last_col (ω_y likewise), every pixel whose
// centre lies in the closed rectangle. Throws std::invalid_argument naming the window and n
// when no pixel centre lies inside it (a window narrower than a pixel).
struct PixelBox {
    int first_row = 0, last_row = -1, first_col = 0, last_col = -1;
};
PixelBox window_pixels(const OmegaWindow& window, int n);

struct PreviewOptions {
    PreviewScale scale = PreviewScale::Log;
    double log_decades = 5.0;     // Log: decades below the peak that are shown; (0, 30]
    double exposure_stops = 0.0;  // Linear: finite
    bool reinhard = false;        // Linear: x/(1+x) before the sRGB curve
    bool false_colour = false;    // the luminance through viridis instead of grey/colour
    bool colour_bar = false;      // a bar with tick labels right of the picture
    std::string unit;             // the bar's caption (e.g. "1/sr"); drawn when it fits
    // ω axes: a frame with ticks and labels of ω_y (columns, below, labelled "wy") and ω_x
    // (rows, left, "wx") around the picture.
    bool axes = false;
    // Only the pixels inside this window (window_pixels), scaled up by a whole factor to at
    // least 256 pixels on the longer side (at most 16 times) when it is smaller; the log
    // scale's peak is the window's. Square slices only.
    bool has_window = false;
    OmegaWindow window;
};

// Throws std::domain_error naming the value when log_decades is not in (0, 30] or
// exposure_stops is not finite.
void validate_preview_options(const PreviewOptions& options);

// An 8-bit RGB picture, row-major, interleaved: rgb[(i * cols + j) * 3 + c]. When a colour bar
// was drawn, bar_* give its rectangle (inclusive rows bar_top…bar_bottom, columns
// bar_left…bar_right; the top row shows the highest value); otherwise they are −1.
struct Preview8 {
    int rows = 0;
    int cols = 0;
    std::vector<std::uint8_t> rgb;
    int bar_top = -1, bar_bottom = -1, bar_left = -1, bar_right = -1;
    // Where the slice's pixels are in the picture (after axes or a table's labels moved them):
    // rows image_top… image_top + image_rows − 1, likewise columns. Each slice pixel covers
    // magnify × magnify picture pixels (a window scaled up; 1 otherwise).
    int image_top = 0, image_left = 0, image_rows = 0, image_cols = 0, magnify = 1;
};

// The log preview's level of `value` in [0, 1]: 1 + log10(value / peak) / decades, clamped;
// 0 for a value ≤ 0 or not finite, or a peak ≤ 0 or not finite. decades > 0.
double log_level(double value, double peak, double decades);

// The viridis colour map at t (clamped to [0, 1]): sRGB components in [0, 1], linearly
// interpolated between the 256 published entries (entry k at t = k/255).
std::array<double, 3> viridis(double t);

// Draws `text` (digits, '.', ',', '-', '+', 'e', '/', 's', 'r', 'u', 'm', 'w', 'x', 'y', ' ';
// other characters are blank) in the 3×5 font scaled by `scale` (1…16) with its top-left at (row, col), in `grey`;
// pixels outside the picture are skipped. Each character advances 4·scale columns.
void draw_text(Preview8& picture, int row, int col, const std::string& text, int scale, std::uint8_t grey);

// The width in pixels draw_text gives `text` at `scale` (4·scale per character, less the last gap).
int text_width(const std::string& text, int scale);

// The preview of a linear RGB slice image (as render writes it): the luminance
// 0.2126 R + 0.7152 G + 0.0722 B sets the level. Log without false colour keeps each pixel's
// hue (RGB scaled so its largest channel is the level; a grey slice gives grey level·255);
// Linear is write_rgb_png's mapping. Non-finite values show black. Throws as
// validate_preview_options and std::invalid_argument for an image whose data does not hold
// rows·cols·3 values or whose side is not 1…16384.
Preview8 make_slice_preview(const RgbImage& image, const PreviewOptions& options);

// The preview of a heightfield: heights min → level 0, max → 1 (a flat field mid grey), grey
// or viridis; the colour bar is labelled in µm (vscale · texel_um · value).
Preview8 make_heightfield_preview(const Heightfield& heightfield, bool false_colour, bool colour_bar);

// The preview of a table's mosaic (table.h table_mosaic: lights_rows × lights_cols tiles of
// n × n pixels): each tile tone-mapped as write_rgb_png does at `exposure_stops` with Reinhard,
// one-pixel grey grid lines between and around the tiles, each light row labelled on the left
// with its ω_i,x (`light_x`) and each light column on top with its ω_i,y (`light_y`) (a column
// label wider than its tile is left out). Throws
// std::invalid_argument for a mosaic that does not hold the tiles or label counts that differ.
Preview8 make_table_preview(const RgbImage& mosaic, int n, const std::vector<double>& light_x,
                            const std::vector<double>& light_y, double exposure_stops);

// Writes a picture as an 8-bit RGB PNG (atomically, as io.h's writers).
void write_preview_png(const std::string& path, const Preview8& picture);

}  // namespace wavebrdf
