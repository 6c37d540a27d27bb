#pragma once
// Files for fabricating a designed relief: a 16-bit grey PNG for grayscale lithography, the
// binary masks of multi-step lithography with their etch depths, and a closed binary STL solid
// for 3-D printing and two-photon writers.
//
// The relief is `rows` × `cols` square texels of constant height (row-major heights_um[i * cols
// + j], µm), as a mask writer makes it: texel (i, j) covers x ∈ [i w, (i+1) w) along the rows
// and y ∈ [j w, (j+1) w) along the columns (w = texel_um), the frame of heightfield.h. Every
// writer writes a temporary file beside its target and renames it (io.h's
// write_file_atomically), so a failed write leaves no partial file; every size is checked
// before anything is allocated.
#include <string>
#include <vector>

namespace wavebrdf {

// The largest relief the writers take: k_max_exr_pixels (16384² texels), the largest
// heightfield wavebrdf reads or makes.
constexpr long long k_max_fabrication_texels = 16384LL * 16384LL;

// The most levels multi-step lithography is described with here (8 binary-weighted masks).
constexpr int k_max_fabrication_levels = 256;

// Writes `heights_um` as a 16-bit grey PNG: height h ∈ [0, height_range_um] ↦ round(h /
// height_range_um · 65535) (0 black = lowest, 65535 white = highest). Its tEXt chunks say how
// to read it back: "wavebrdf:height_range_um", "wavebrdf:texel_um", "wavebrdf:units" ("height
// in um = value / 65535 * height_range_um") and "Software"; a pHYs chunk gives the texel pitch
// in pixels per metre (rounded to an integer, as PNG stores it).
// height_range_um: H > 0, finite; texel_um: k_min_texel_um … k_max_texel_um (heightfield.h).
// Throws std::invalid_argument when rows or cols < 1, rows · cols exceeds
// k_max_fabrication_texels or differs from heights_um.size(), H or texel_um is out of range, or a
// height is not finite or lies outside [0, H] by more than 1e-9 H (values within that are
// clamped); std::runtime_error when the file cannot be written.
void write_heights_png16(const std::string& path, const std::vector<double>& heights_um, int rows, int cols,
                         double height_range_um, double texel_um);

// One mask of multi-step lithography (write_level_masks).
struct LevelMask {
    std::string path;         // the PNG written
    double depth_um = 0.0;    // what an exposed texel loses in this step, µm
    int weight = 0;           // depth_um in units of one level step
};

// The masks of multi-step lithography that make the K-level relief `level_index` (row-major,
// each 0 … levels − 1; level k is height k · step, step = height_range_um / (levels − 1)). The
// process starts from a flat plate at the top height (level K − 1) and etches: texel (i, j)
// must lose (K − 1 − k) steps. With K a power of two, log2 K masks with binary-weighted depths:
// mask m exposes the texels whose etch count K − 1 − k has bit m set and is etched 2^m steps
// deep. Otherwise K − 1 masks of one step each: mask m exposes the texels with K − 1 − k ≥ m +
// 1 (cumulative masks: each exposes a subset of the one before). Either way the depths of the
// masks exposing a texel sum to its etch count times the step.
// Writes `prefix`_NN.png (NN = 01, 02, …, the order of the steps; 1-bit grey PNG, white = 1 =
// exposed/etched, black = protected; the same texel frame as heights.png) and `prefix`.json
// (DIR/masks_01.png … and DIR/masks.json for prefix DIR/masks): the level count, step, height range, texel, process
// and, per mask in order, its file name, depth_um and weight. Returns the masks in order.
// levels: 2 … k_max_fabrication_levels; height_range_um > 0 finite; texel_um as above.
// Throws std::invalid_argument for a size as write_heights_png16's, levels out of range or a
// level index outside 0 … levels − 1 (naming the first such texel); std::runtime_error when a
// file cannot be written (the masks written before it stay).
std::vector<LevelMask> write_level_masks(const std::string& prefix, const std::vector<int>& level_index, int rows,
                                         int cols, int levels, double height_range_um, double texel_um);

// The number of masks write_level_masks writes for `levels` (log2 K for a power of two, else
// K − 1); throws std::invalid_argument for levels outside 2 … k_max_fabrication_levels.
int level_mask_count(int levels);

// The number of triangles write_stl writes for this relief (without writing it). Same checks.
long long stl_triangle_count(const std::vector<double>& heights_um, int rows, int cols, double base_um);

// Writes the texel relief as a closed solid in binary STL, coordinates in µm: a flat top per
// texel at its height (two triangles), vertical walls between neighbouring texels of different
// height, side walls around the tile down to the base plane z_base = min(0, min h) − base_um,
// and the bottom at z_base. Vertices are shared exactly (walls are split at every height
// meeting at a corner, so no vertex lies inside another triangle's edge) and every triangle is
// wound counter-clockwise seen from outside, its stored normal pointing out. Where two texel
// columns touch only along a vertical edge (a 2 × 2 saddle: high, low, high, low around a
// corner), that edge is shared by four triangles, as the solid itself is non-manifold there;
// every other edge is shared by exactly two. The volume is Σ w² (h − z_base).
// base_um: > 0, finite, at most 1e6. Throws std::invalid_argument for sizes as
// write_heights_png16's, a non-finite height or base, or more than 2^32 − 1 triangles (binary
// STL's limit; the count is named); std::runtime_error when the file cannot be written.
void write_stl(const std::string& path, const std::vector<double>& heights_um, int rows, int cols, double texel_um,
               double base_um = 1.0);

// What write_fabrication_exports wrote.
struct FabricationFiles {
    std::string heights_png;          // DIR/heights.png
    std::string heights_stl;          // DIR/heights.stl
    std::string masks_json;           // DIR/masks.json ("" for a grayscale relief)
    std::vector<LevelMask> masks;     // DIR/masks_NN.png (empty for a grayscale relief)
    long long stl_triangles = 0;      // the STL's triangles (84 + 50 per triangle bytes)
    std::string note;                 // why the STL was not written ("" when it was)
    std::string heights_x3p;          // DIR/heights.x3p ("" when not written)
    std::string x3p_note;             // why heights.x3p was not written ("" when it was)
};

// Writes the fabrication files of a relief into the existing directory `out_dir`:
// heights.png (write_heights_png16), heights.stl (write_stl with base_um = max(height_range_um,
// texel_um)) and, when levels > 0, masks_01.png … and masks.json (write_level_masks; each
// height must then lie within 1e-6 · step of a level k · step, else std::invalid_argument naming
// the texel). levels = 0: a grayscale relief, no masks. The STL takes 84 + 50 bytes per
// triangle, 2 to about 8 triangles per texel (a random 8-level 1024² relief: 375 MB): when it
// would exceed max_stl_bytes it is not written, heights_stl is "" and `note` says why.
// heights.x3p: the heights as ISO 25178-72 x3p (write_surface, surface_file.h: float64 µm, rows
// along y), where the x3p plugin loads and its copies (about 24 bytes a texel) stay within
// max_stl_bytes; else heights_x3p is "" and x3p_note says why. Checks as the writers'.
FabricationFiles write_fabrication_exports(const std::string& out_dir, const std::vector<double>& heights_um, int rows,
                                           int cols, double texel_um, double height_range_um, int levels,
                                           double max_stl_bytes = 4e9);

}  // namespace wavebrdf
