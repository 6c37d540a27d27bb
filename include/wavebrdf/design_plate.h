#pragma once
// A spatially varying design (docs/design.md, "Plate"): a picture shown by a plate whose regions
// each carry one of a palette of periodic tile designs, written as one heightfield.
//
// Every palette entry is designed once as a periodic tile by the single-tile designer
// (design_run.h): a colour entry `#RRGGBB` as a colour target (white light into the view cone),
// a direction entry `dir:X,Y` as a highlight (as much of the light as possible into the view
// cone about ω_o = (X, Y)). Each picture pixel takes one entry (colours: the nearest in CIELUV;
// directions: by the pixel's luminance, darkest → first entry), and the plate is the picture's
// pixels, each a square of `plate_pixel_um` (a whole number of tile periods) filled with its
// entry's tile. Plate texel (I, J) of a pixel with entry e is tile texel (I mod N, J mod N) of e,
// so neighbouring pixels of one entry join without a seam. Picture rows run along the plate's
// rows (x), as heights.png shows them.
#include <array>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "wavebrdf/design_run.h"

namespace wavebrdf {

struct PaletteEntry {
    std::string text;                 // as given
    bool direction = false;           // dir:X,Y (else a colour)
    std::array<int, 3> srgb8{{0, 0, 0}};
    std::array<double, 3> linear_rgb{{0.0, 0.0, 0.0}};
    std::array<double, 2> omega{{0.0, 0.0}};  // direction entries: the highlight's ω_o
};

// The most entries a palette may have.
constexpr int k_max_palette_entries = 64;

// Parses `--palette`: entries separated by ';', whitespace or (between colours) ','; each
// `#RRGGBB` or `dir:X,Y` (|(X, Y)| < 1); one kind only, 2 … k_max_palette_entries entries, no
// duplicates. std::invalid_argument naming the entry.
std::vector<PaletteEntry> parse_palette(const std::string& text);

// A picture: 8-bit sRGB, row-major, interleaved RGB.
struct PlatePicture {
    int rows = 0, cols = 0;
    std::vector<std::uint8_t> srgb8;
    std::string file;
};

// The most picture pixels a side (the plate is at least one texel per pixel).
constexpr int k_max_picture_side = 16384;

// Reads a PNG (any bit depth, grey or colour; alpha dropped) as 8-bit sRGB. The size is checked
// on the header before any pixel is allocated: 1 … k_max_picture_side a side and at most
// max_pixels pixels. std::invalid_argument naming the file.
PlatePicture read_plate_picture(const std::string& path, long long max_pixels = 16384LL * 16384LL);

// Texels a picture pixel spans per side: plate_pixel_um / texel_um, which must be a whole number
// (≥ 1) of tile periods (size · texel_um); 0 means one period. std::domain_error naming the value.
int plate_pixel_texels(const DesignOptions& design, double plate_pixel_um);

struct PlateOptions {
    // The tile, light, view and optimisation every entry shares (its target is not used;
    // direction entries take their own view). White light (--spectral N ≥ 3) is required.
    DesignOptions design;
    PlatePicture picture;
    std::vector<PaletteEntry> palette;
    double plate_pixel_um = 0.0;  // a picture pixel's side on the plate; 0: one tile period
};

struct PreparedPlate {
    PlateOptions options;
    int pixel_texels = 0;         // texels a picture pixel spans, per side (a multiple of the tile's N)
    int rows = 0, cols = 0;       // the plate's texels
    std::vector<int> assignment;  // per picture pixel, its palette entry
    std::vector<long long> pixels_per_entry;
    std::string mapping;          // how pixels were mapped to entries, in words
    double estimated_bytes = 0.0;
    std::vector<std::string> notes;
};

// Checks everything (the palette against the picture, the plate pixel against the tile period,
// the plate's size against k_max_fabrication_texels, every entry's design options through
// prepare_design), maps the pixels, and refuses (OutOfMemory) an estimate above the memory
// limit — the largest entry design plus the plate and its exports — before any work.
PreparedPlate prepare_plate(const PlateOptions& options);

struct PlateResult {
    int rows = 0, cols = 0;
    double texel_um = 0.0;
    std::vector<double> heights_um;  // rows × cols, row-major
    std::vector<double> levels_um;
    std::vector<DesignResult> tiles;  // per palette entry (size 0 when no pixel uses it)
    // The picture and its appearance, one panel per view (colours: the view; directions: each
    // entry's direction): linear sRGB per picture pixel, interleaved, from exact scalar
    // diffraction of each entry's tile into the view cone (power fractions of the incident light).
    int picture_rows = 0, picture_cols = 0;
    std::vector<float> picture_linear;
    std::vector<std::vector<float>> appearance;
    std::vector<std::string> view_names;
    std::string metrics_json;  // design.json
};

// Designs every entry that a pixel uses, in turn (on_step gets the entry index and each step;
// returning false stops that entry's design early), assembles the plate and scores each entry's
// tile by exact scalar diffraction under every view.
PlateResult run_plate(const PreparedPlate& prepared,
                      const std::function<bool(int entry, const DesignStep&)>& on_step = {});

// Writes the run directory: design.json, heights.exr (and heights.x3p), the fabrication files (heights.png,
// masks, heights.stl when under 1 GB), plate.png (the picture beside its appearance) and
// plate.exr (the appearance panels side by side, linear).
void write_plate_directory(const std::string& dir, const PlateResult& result, bool force);

}  // namespace wavebrdf
