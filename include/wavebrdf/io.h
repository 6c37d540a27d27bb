#pragma once
// File input and output: OpenEXR heightfields and images, PNG previews, text files.
// Every writer writes to a temporary file beside the target (named `<path>.tmp-<pid>-<n>`,
// unique per process and write) and renames it into place, so an interrupted or failed write
// never leaves a partial output file, and two writers of one path never mix their contents
// (the last rename wins). A writer replaces only a regular file: when `path` exists and is
// anything else (directory, symbolic link, FIFO, socket, device node such as /dev/null) it
// throws std::runtime_error "<path>: is a ..., not a regular file; refusing to replace it" and
// touches nothing. Symbolic links are refused too, even to a regular file (write to the link's
// target instead); links among the parent directories are followed as usual. (The check and
// the rename are two steps: a file another process puts at `path` in between is replaced.)
// Temporary files in progress are listed in a fixed-size table that a signal handler may empty
// with remove_temporary_files(), so a process killed by a handled signal leaves none behind.
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "wavebrdf/heightfield.h"
#include "wavebrdf/model.h"

namespace wavebrdf {

// An RGB image in linear float, row-major, channel-interleaved: data[(i * cols + j) * 3 + c].
struct RgbImage {
    int rows = 0;
    int cols = 0;
    std::vector<float> data;
};

// The most pixels an EXR file read here may declare (16384², the largest heightfield
// `wavebrdf heightfield --size` makes): checked on the header, before any pixel is allocated,
// so a small file declaring a huge data window fails with its size, not std::bad_alloc.
// Not tied to the file size: compressed constant images are legitimately tiny.
constexpr long long k_max_exr_pixels = 16384LL * 16384LL;
// Per side, channels and tile size: what OpenEXR allocates when it opens a file (line-offset
// tables, compressor and tile buffers) grows with these, so they are checked on the raw header
// before OpenEXR reads it. OpenEXR's own default tile is 64x64.
constexpr long long k_max_exr_side = 16384;
constexpr int k_max_exr_channels = 64;
constexpr long long k_max_exr_tile_pixels = 1024LL * 1024LL;

// Self-describing files (docs/conventions.md, "Files"): the header attributes wavebrdf writes,
// all named with the prefix "wavebrdf:". Strings read back are at most k_max_attribute_chars
// bytes; a longer one, a value of the wrong type or out of range is refused with
// std::runtime_error naming the file and the attribute.
constexpr std::size_t k_max_attribute_chars = 4096;

// What a heightfield EXR says about itself; an absent field means the file does not say (files
// of genBrdf and of wavebrdf before 0.2 say nothing; readers then use their defaults).
struct HeightfieldAttributes {
    std::optional<double> texel_um;  // "wavebrdf:texel_um" (double): texel width w, µm
    std::optional<double> vscale;    // "wavebrdf:vscale" (double): vertical scale v
    std::string units;               // "wavebrdf:units" (string): how to read the values
    std::string made_by;             // "wavebrdf:made_by" (string): generator and parameters
    std::string version;             // "wavebrdf:version" (string): the writer's wavebrdf version
};

// The text every heightfield EXR carries in "wavebrdf:units".
constexpr const char* k_heightfield_units = "height in um = value * vscale * texel_um (values in texel widths)";

// Reads only the header attributes of a heightfield EXR (no pixels). texel_um is checked against
// k_min_texel_um … k_max_texel_um, vscale against the Heightfield's range (0, or 1e-6 … 1e4 in
// magnitude). Errors as read_heightfield_exr's, and std::runtime_error "<path>: attribute
// 'wavebrdf:texel_um' ..." for a hostile attribute.
HeightfieldAttributes read_heightfield_attributes(const std::string& path);

// Reads the R channel of an OpenEXR file (half or float pixels, any size) as a heightfield in
// the public release's convention (values in units of texel width; row i = image row).
// texel_um (µm) and vscale: the caller's values when given, else the file's attributes, else
// 1.0 (use resolve_heightfield_scale to warn when a given value disagrees with the file).
// Throws std::runtime_error naming the file when it is missing, unreadable, corrupt or
// truncated, declares more than k_max_exr_pixels pixels, has no R channel (a single Y channel
// is accepted too), is a multi-part file of two or more parts (refused rather than silently
// reading part 0; a one-part file written through the multi-part API is read), or has a
// hostile wavebrdf attribute; std::domain_error when a value is not finite.
Heightfield read_heightfield_exr(const std::string& path, std::optional<double> texel_um = std::nullopt,
                                 std::optional<double> vscale = std::nullopt);

// The heightfield, the scale it was read with and what the file said, in one read.
struct HeightfieldFile {
    Heightfield heightfield;
    HeightfieldAttributes attributes;
};
HeightfieldFile read_heightfield_exr_file(const std::string& path, std::optional<double> texel_um = std::nullopt,
                                          std::optional<double> vscale = std::nullopt);

// Reads only what one footprint's slice needs: the rows of the heightfield EXR within
// ceil(3 sigma_p_um / w) + 3 rows (w the texel width used) of the footprint centre x_um (µm along
// the rows, any value: it is reduced to one period; the distance wraps across the tile's edge),
// a superset of the rows of every kernel
// within 3 sigma_p (gabor.h footprint_kernels) and of the neighbours its slope uses. Every other
// value of the returned full-size heightfield is 0, so it renders that footprint (x_um,
// sigma_p_um and any y_um) bit for bit as the whole file does, and nothing else. A footprint
// covering every row reads the whole file. Decompresses only the chunks of those rows, so damage
// elsewhere in the pixels (a truncated tail, a non-finite value) goes unnoticed; the header is
// checked as read_heightfield_exr_file checks it, with its errors. texel_um / vscale as there.
// Throws std::domain_error for a non-finite x_um or a sigma_p_um that is not finite and > 0.
HeightfieldFile read_heightfield_exr_footprint(const std::string& path, double x_um, double sigma_p_um,
                                               std::optional<double> texel_um = std::nullopt,
                                               std::optional<double> vscale = std::nullopt);

// Which texel width and vertical scale to use for the file at `path` whose attributes are
// `file`: the given value when there is one, else the file's, else the default. `warnings`
// has one line per given value that differs from the file's, naming both, e.g.
// "--texel-um 1 disagrees with g.exr's texel_um 0.5; using 1" (`texel_option` and
// `vscale_option` are the names the caller's user knows: "--texel-um", "-w", "texel_um").
// Throws std::domain_error naming `path` when the chosen texel_um or vscale is out of the
// Heightfield's range (then there are no warnings to show).
struct HeightfieldScale {
    double texel_um = 1.0;
    double vscale = 1.0;
    std::vector<std::string> warnings;
};
HeightfieldScale resolve_heightfield_scale(const std::string& path, const HeightfieldAttributes& file,
                                           std::optional<double> texel_um, std::optional<double> vscale,
                                           const std::string& texel_option = "--texel-um",
                                           const std::string& vscale_option = "--vscale", double default_texel_um = 1.0,
                                           double default_vscale = 1.0);

// Writes the heightfield's raw values (texel units) as a single-channel float EXR (channel R),
// with the attributes: its texel_um and vscale, k_heightfield_units, `made_by` (how it was
// made: a generator and its parameters, "python", "library"; at most k_max_attribute_chars
// bytes, longer is cut) and the wavebrdf version.
void write_heightfield_exr(const std::string& path, const Heightfield& heightfield,
                           const std::string& made_by = "library");

// Writes a grey PNG preview of a heightfield, min → black, max → white.
void write_heightfield_png(const std::string& path, const Heightfield& heightfield);

// An n × n slice of `channels` (1 or 3) values per pixel (row-major, interleaved, as
// render_observation returns it) as an RGB float image: one channel becomes grey (R = G = B).
RgbImage to_image(const std::vector<double>& slice, int n, int channels);

// Writes an RGB float EXR (channels R, G, B). With `with_alpha`, also an A channel set to 1
// (the layout of genBrdf's output).
void write_rgb_exr(const std::string& path, const RgbImage& image, bool with_alpha = false);

// Reads the R, G, B channels of an EXR (half or float) as linear float. Errors as
// read_heightfield_exr's (k_max_exr_pixels, multi-part files of two or more parts refused).
RgbImage read_rgb_exr(const std::string& path);

// The unit of every slice wavebrdf renders (render_rgb, brdf.h; docs/conventions.md): the BRDF.
constexpr const char* k_slice_unit =
    "f_r (BRDF) in 1/sr; one wavelength: R = G = B = f_r; several: linear sRGB (D65) of f_r(lambda), "
    "a constant f_r = c giving (c, c, c)";

// What a slice EXR says about itself: the query that rendered it, the heightfield it came from
// and its unit. Stored as "wavebrdf:" attributes (docs/conventions.md, "Files").
struct SliceAttributes {
    Query query;                     // x_um, y_um, sigma_p_um (µm), omega_i, model
    std::vector<double> lambdas_um;  // the wavelengths, µm (one: monochrome)
    int resolution = 0;              // n of the n × n slice
    int channels = 3;                // 1 (one wavelength, stored as R = G = B) or 3
    // The heightfield it was rendered from: rows 0 when none is known (an observation given
    // as a list or measured), and then texel_um, vscale and heightfield_file are not stored.
    int heightfield_rows = 0, heightfield_cols = 0;
    double texel_um = 1.0;         // its texel width, µm
    double vscale = 1.0;           // and vertical scale
    std::string heightfield_file;  // "" when it came from no file
    std::string unit = k_slice_unit;
    std::string made_by;  // the program that wrote it ("wavebrdf render", ...)
    std::string version;  // set by write_slice_exr to this wavebrdf's; read back as stored
};

// Writes an RGB slice as write_rgb_exr does, with `attributes` in its header (the version is
// this build's). Strings longer than k_max_attribute_chars are cut.
void write_slice_exr(const std::string& path, const RgbImage& image, const SliceAttributes& attributes,
                     bool with_alpha = false);

// Reads a slice EXR: the image (read_rgb_exr) and, when the file carries wavebrdf's slice
// attributes, what they say (std::nullopt for a file without them). A file that has some of
// them must have all, of the right types and in range (std::runtime_error naming the file and
// the attribute otherwise).
struct SliceFile {
    RgbImage image;
    std::optional<SliceAttributes> attributes;
};
SliceFile read_slice_exr(const std::string& path);

// Writes an 8-bit sRGB PNG preview: value · 2^exposure, Reinhard-free clamp to [0, 1], sRGB
// transfer curve. With `tonemap`, x/(1+x) (Reinhard) is applied before the transfer curve.
void write_rgb_png(const std::string& path, const RgbImage& image, double exposure = 0.0, bool tonemap = false);

// Writes a little-endian float64 NumPy .npy array of the given shape (C order), for the
// Python plotting scripts. Atomic like every writer here.
void write_npy(const std::string& path, const std::vector<std::size_t>& shape, const std::vector<double>& data);

// Exposure (in stops) that maps the 99.9th percentile of `slice` to about 4 before Reinhard
// (write_rgb_png's previews of slices); 0 for an empty or non-positive slice.
double auto_exposure(const std::vector<double>& slice);

// Throws std::runtime_error when `path` cannot be created (missing directory, no permission)
// or exists and is not a regular file (see the top of this header), without leaving a file
// behind. Lets a command fail before long work, not after it.
void check_writable(const std::string& path);

// The atomic write every writer here uses: refuses a non-regular `path` (see the top of this
// header), calls `write(temporary_path)`, which must create and fill that file, and renames it
// onto `path`. On any failure the temporary is removed and std::runtime_error naming `path`
// (and the cause) is thrown; an existing `path` is then unchanged.
void write_file_atomically(const std::string& path,
                           const std::function<void(const std::string& temporary_path)>& write);

// Writes `text` (bytes as given, no newline added) to `path` through write_file_atomically.
void write_text_atomically(const std::string& path, const std::string& text);

// Removes (unlink) every temporary file of a write in progress in this process. Async-signal-
// safe: meant for a handler of SIGINT/SIGTERM that then ends the process. A write in progress
// on another thread is waited for (up to 5 s): it removes its own temporary and throws instead
// of moving the file into place, and every later write throws at once. The table holds 64
// writes in progress at once with paths up to 4095 bytes; a write beyond that still works but
// its temporary is not removed by this call.
void remove_temporary_files() noexcept;

// Throws std::invalid_argument when `path` (not empty) does not end in one of `extensions`
// (".exr", compared ignoring case): an output is written in the format its name says or not at
// all, so `--out x.png` never holds EXR data. The message names the option (as the front end spells
// it: `--out`, `path`), the path and the extensions this output writes. A path that exists and is
// not a regular file (a FIFO, a device) passes: its writer refuses it with its own message.
void check_output_format(const std::string& option, const std::string& path,
                         const std::vector<std::string>& extensions);

}  // namespace wavebrdf
