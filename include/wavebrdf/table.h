#pragma once
// Tabulated BRDFs (docs/table.md): the slices of one footprint over a regular grid of light
// directions, and the one self-describing OpenEXR file that stores them.
//
// The light grid is the slice convention applied to ω_i, scaled by `max_sin` (= sin θ_i at the
// grid's edge): light (a, b), a = 0…rows−1 along x, b = 0…cols−1 along y, is
//   ω_i = (max_sin · ((a + ½)/rows · 2 − 1), max_sin · ((b + ½)/cols · 2 − 1)),
// and only lights with |ω_i|² ≤ max_sin² are rendered; the others (the square grid's corners)
// are zero, as slice pixels outside the unit disk are. Each light's entry is an n × n RGB slice
// over ω_o exactly as render_rgb returns it (brdf.h; pixel (p, q) at ω_o = (slice_omega(p, n),
// slice_omega(q, n)), zero outside the unit disk): f_r in 1/sr, one wavelength in R = G = B,
// several mixed to linear sRGB (spectrum.h).
//
// The file is one single-part RGB float EXR, a mosaic of rows × cols tiles of n × n pixels:
// image row a·n + p, column b·n + q holds value (a, b, p, q). Header attributes (wavebrdf:*)
// give the footprint, model, wavelengths, resolution, light grid, ω_o mapping, unit and the
// writer's version (the list is in docs/table.md).
#include <array>
#include <string>
#include <vector>

#include "wavebrdf/brdf.h"
#include "wavebrdf/communicator.h"
#include "wavebrdf/heightfield.h"
#include "wavebrdf/model.h"

namespace wavebrdf {

// The light directions of a table: rows × cols on the projected disk of radius max_sin.
struct LightGrid {
    int rows = 32;         // lights along ω_i,x: 1 … 16384 (and rows · n ≤ 16384, see below)
    int cols = 32;         // lights along ω_i,y: 1 … 16384 (and cols · n ≤ 16384)
    double max_sin = 0.9;  // sin θ_i at the grid's edge: 0 < max_sin < 1
};

// ω_i component of light `index` of `count` along one axis: max_sin · ((index + ½)/count · 2 − 1).
inline double light_grid_omega(int index, int count, double max_sin) {
    return max_sin * ((index + 0.5) / count * 2.0 - 1.0);
}

// The most pixels per side of a table's mosaic (k_max_exr_side of io.h): rows · n and cols · n.
constexpr long long k_max_table_side = 16384;

// What a table renders: the footprint and model of `query` (its omega_i is ignored; each light
// sets its own), the wavelengths, the slice resolution and the light grid.
struct TableSpec {
    Query query;
    std::vector<double> lambdas_um;  // one: R = G = B; several: CIE 1931 → linear sRGB (1 … 256)
    bool spectral = false;           // the wavelengths came from --spectral (recorded in the file)
    int resolution = 64;             // n: each slice n × n, 1 … 8192
    LightGrid lights;
    bool double_precision = false;  // render each slice in double (values are stored as float)
};

// A table in memory (or read from a file).
struct BrdfTable {
    TableSpec spec;
    // Heightfield facts recorded with it (the footprint's surface): size and scales.
    int heightfield_rows = 0, heightfield_cols = 0;
    double texel_um = 1.0, vscale = 1.0;
    std::string version;          // wavebrdf version that wrote the table
    // "" for a table rendered from a surface; otherwise what made it instead (an analytic lobe,
    // lobe.h), stored as the optional attribute wavebrdf:source.
    std::string source;
    std::vector<double> light_x;  // rows values: ω_i,x of each light row (light_grid_omega)
    std::vector<double> light_y;  // cols values: ω_i,y of each light column
    // rows · cols flags (row-major): 1 where the light was rendered (|ω_i| ≤ max_sin), 0 where
    // its slice is all zero.
    std::vector<unsigned char> rendered;
    // f_r in 1/sr, C order (rows, cols, n, n, 3): values[(((a · cols + b) · n + p) · n + q) · 3 + c].
    std::vector<float> values;
};

// Throws std::invalid_argument / std::domain_error (one line naming the value) unless `spec` is
// valid: validate(query) with ω_i ignored, wavelengths as render_rgb, 1 ≤ resolution ≤ 8192,
// rows, cols ≥ 1, rows · n and cols · n ≤ k_max_table_side, 0 < max_sin < 1.
void validate(const TableSpec& spec);

// Light directions of the grid: light_x (rows), light_y (cols) and the rendered flags.
void light_grid_axes(const LightGrid& grid, std::vector<double>& light_x, std::vector<double>& light_y,
                     std::vector<unsigned char>& rendered);

// Estimated peak memory (bytes) of render_brdf_table plus writing it: the table's values, the
// mosaic written from them (4 bytes per value each) and one slice's render (estimate_render_bytes).
double estimate_table_bytes(const Heightfield& heightfield, const TableSpec& spec, const RenderOptions& options);

// Renders the table: validates `spec`, refuses (OutOfMemory, before allocating) what
// estimate_table_bytes says exceeds options.max_memory_gb (0: physical memory), then renders the
// rendered lights one light row at a time, each row one render_batch (batch.h: the lights spread
// over the threads, one slice per thread). options.progress advances by
// work_units(n) · wavelengths per light (size it with table_work_units); check_interrupt is
// polled between lights (Interrupted; render_batch polls between its items). Each entry equals render_rgb's slice for that light bit
// for bit (in float, or double rounded to float).
//
// With `comm` of several ranks (docs/scale.md): the rendered lights, in row-major order, are
// split into contiguous blocks (render_batch_over_ranks), each rank renders its block and rank 0
// gathers them: rank 0's table equals the one-process table bit for bit; the other ranks get
// the table's description with `values` empty. Failures are agreed (run_agreed: RankFailed on every rank);
// options.progress advances by this rank's block (table_work_units(spec, comm)). Collective.
BrdfTable render_brdf_table(const Heightfield& heightfield, const TableSpec& spec, const RenderOptions& options = {},
                            const Communicator& comm = serial_communicator());

// Units of progress render_brdf_table reports for `spec` (on `comm`'s rank: its block's).
long long table_work_units(const TableSpec& spec, const Communicator& comm = serial_communicator());

// Writes `table` as the mosaic EXR described at the top (atomically, write_file_atomically).
// Throws std::invalid_argument when its sizes disagree with its spec.
void write_brdf_table(const std::string& path, const BrdfTable& table);

// Reads a table file written by write_brdf_table. Refuses (std::runtime_error naming the
// file and the attribute or size) anything but such a file: missing or mistyped wavebrdf:*
// attributes, values out of their ranges, declared sizes beyond k_max_table_side, a mosaic
// whose size disagrees with rows · n × cols · n (naming both), light axes that disagree with
// the grid, non-finite values. The EXR itself is read with read_rgb_exr's checks (io.h).
BrdfTable read_brdf_table(const std::string& path);

// Row-major (rows · n) × (cols · n) mosaic image of the table's values (the file's pixels).
std::vector<float> table_mosaic(const BrdfTable& table);

}  // namespace wavebrdf
