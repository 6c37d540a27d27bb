#include "wavebrdf/fabrication.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <csetjmp>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <functional>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <png.h>

#include "wavebrdf/heightfield.h"
#include "wavebrdf/io.h"
#include "wavebrdf/surface_file.h"
#include "wavebrdf/version.h"

namespace wavebrdf {
namespace {

std::string full_precision(double value) {
    std::ostringstream out;
    out.precision(17);
    out << value;
    return out.str();
}

// The checks every writer shares, before anything is allocated.
void check_size(int rows, int cols, std::size_t values, const char* what) {
    if (rows < 1 || cols < 1)
        throw std::invalid_argument(std::string(what) + ": rows " + std::to_string(rows) + " and cols " +
                                    std::to_string(cols) + " must both be at least 1");
    const long long texels = static_cast<long long>(rows) * cols;
    if (texels > k_max_fabrication_texels)
        throw std::invalid_argument(std::string(what) + ": " + std::to_string(rows) + " x " + std::to_string(cols) +
                                    " texels exceed the largest relief written, " +
                                    std::to_string(k_max_fabrication_texels));
    if (static_cast<long long>(values) != texels)
        throw std::invalid_argument(std::string(what) + ": " + std::to_string(values) + " values for " +
                                    std::to_string(rows) + " x " + std::to_string(cols) + " texels");
}

void check_texel(double texel_um, const char* what) {
    if (!(texel_um >= k_min_texel_um && texel_um <= k_max_texel_um))
        throw std::invalid_argument(std::string(what) + ": texel_um " + full_precision(texel_um) + " is outside " +
                                    full_precision(k_min_texel_um) + " ... " + full_precision(k_max_texel_um));
}

void check_range(double height_range_um, const char* what) {
    if (!(std::isfinite(height_range_um) && height_range_um > 0.0))
        throw std::invalid_argument(std::string(what) + ": height_range_um " + full_precision(height_range_um) +
                                    " must be finite and > 0");
}

void check_finite_heights(const std::vector<double>& heights_um, int cols, const char* what) {
    for (std::size_t k = 0; k < heights_um.size(); ++k)
        if (!std::isfinite(heights_um[k]))
            throw std::invalid_argument(std::string(what) + ": height at texel (" + std::to_string(k / cols) + ", " +
                                        std::to_string(k % cols) + ") is " + full_precision(heights_um[k]) +
                                        "; expected a finite value in um");
}

// --- PNG through libpng's full API (the simplified one cannot write text chunks or 1-bit) -----

struct PngStatus {
    char message[256] = {0};
};

void on_png_error(png_structp png, png_const_charp message) {
    auto* status = static_cast<PngStatus*>(png_get_error_ptr(png));
    std::snprintf(status->message, sizeof status->message, "%s", message ? message : "unknown error");
    png_longjmp(png, 1);
}

void on_png_warning(png_structp, png_const_charp) {}

// Writes a grey PNG to the open `file`, one row at a time from fill_row (which must not throw).
// Only plain data live in this frame between setjmp and a possible longjmp, so no C++
// destructor is skipped. Returns false with status->message set when libpng fails.
bool write_grey_png_rows(FILE* file, png_uint_32 rows, png_uint_32 cols, int bit_depth, png_text* texts, int n_texts,
                         png_uint_32 pixels_per_metre, const std::function<void(png_uint_32, png_bytep)>* fill_row,
                         png_bytep row_buffer, PngStatus* status) {
    png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, status, on_png_error, on_png_warning);
    if (png == nullptr) {
        std::snprintf(status->message, sizeof status->message, "cannot create a PNG writer");
        return false;
    }
    png_infop info = png_create_info_struct(png);
    if (info == nullptr) {
        png_destroy_write_struct(&png, nullptr);
        std::snprintf(status->message, sizeof status->message, "cannot create a PNG header");
        return false;
    }
    if (setjmp(png_jmpbuf(png))) {
        png_destroy_write_struct(&png, &info);
        return false;
    }
    png_init_io(png, file);
    png_set_IHDR(png, info, cols, rows, bit_depth, PNG_COLOR_TYPE_GRAY, PNG_INTERLACE_NONE,
                 PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
    if (n_texts > 0) png_set_text(png, info, texts, n_texts);
    if (pixels_per_metre > 0) png_set_pHYs(png, info, pixels_per_metre, pixels_per_metre, PNG_RESOLUTION_METER);
    png_write_info(png, info);
    for (png_uint_32 i = 0; i < rows; ++i) {
        (*fill_row)(i, row_buffer);
        png_write_row(png, row_buffer);
    }
    png_write_end(png, info);
    png_destroy_write_struct(&png, &info);
    return true;
}

// Writes a grey PNG of bit depth 1 or 16 atomically; `texts` are (key, value) tEXt chunks.
void write_grey_png(const std::string& path, int rows, int cols, int bit_depth,
                    const std::vector<std::pair<std::string, std::string>>& texts, double texel_um,
                    const std::function<void(png_uint_32, png_bytep)>& fill_row) {
    const std::size_t row_bytes = bit_depth == 16 ? static_cast<std::size_t>(cols) * 2
                                                  : (static_cast<std::size_t>(cols) + 7) / 8;
    std::vector<png_byte> row(row_bytes, 0);
    // png_text holds non-const char pointers; keep the strings alive beside it.
    std::vector<std::string> keys, values;
    for (const auto& [key, value] : texts) {
        keys.push_back(key.substr(0, 79));  // PNG keywords are 1-79 bytes
        values.push_back(value);
    }
    std::vector<png_text> chunks(texts.size());
    for (std::size_t k = 0; k < texts.size(); ++k) {
        std::memset(&chunks[k], 0, sizeof chunks[k]);
        chunks[k].compression = PNG_TEXT_COMPRESSION_NONE;
        chunks[k].key = keys[k].data();
        chunks[k].text = values[k].data();
        chunks[k].text_length = values[k].size();
    }
    // pHYs stores whole pixels per metre: 0.5 um texels are 2,000,000 exactly.
    const double per_metre = std::round(1e6 / texel_um);
    const png_uint_32 pixels_per_metre =
        per_metre >= 1.0 && per_metre <= 2147483647.0 ? static_cast<png_uint_32>(per_metre) : 0;
    write_file_atomically(path, [&](const std::string& tmp) {
        FILE* file = std::fopen(tmp.c_str(), "wb");
        if (file == nullptr) throw std::runtime_error("cannot create " + tmp + ": " + std::strerror(errno));
        PngStatus status;
        const bool ok =
            write_grey_png_rows(file, static_cast<png_uint_32>(rows), static_cast<png_uint_32>(cols), bit_depth,
                                chunks.data(), static_cast<int>(chunks.size()), pixels_per_metre, &fill_row,
                                row.data(), &status);
        const bool write_error = std::ferror(file) != 0;
        const bool close_error = std::fclose(file) != 0;
        if (!ok) throw std::runtime_error(std::string("libpng: ") + status.message);
        if (write_error || close_error) throw std::runtime_error("cannot write " + tmp + ": " + std::strerror(errno));
    });
}

// --- STL -----------------------------------------------------------------------------------

struct Vertex {
    float x, y, z;
};

// The relief with a ring of texels at z_base around it, and the solid's triangles.
class ReliefSolid {
public:
    ReliefSolid(const std::vector<double>& heights_um, int rows, int cols, double texel_um, double base_um)
        : m_heights(heights_um), m_rows(rows), m_cols(cols), m_texel_um(texel_um) {
        double lowest = 0.0;
        for (double h : heights_um) lowest = std::min(lowest, h);
        m_z_base = lowest - base_um;
    }

    double z_base() const { return m_z_base; }

    // Calls emit(a, b, c, outward) for every triangle, in any winding; `outward` is the axis
    // (0 x, 1 y, 2 z) and sign (±1) its normal must have.
    template <typename Emit>
    void triangles(Emit&& emit) const {
        // Flat tops.
        for (int i = 0; i < m_rows; ++i)
            for (int j = 0; j < m_cols; ++j) {
                const double h = height(i, j);
                const Vertex p00 = vertex(i, j, h), p10 = vertex(i + 1, j, h), p11 = vertex(i + 1, j + 1, h),
                             p01 = vertex(i, j + 1, h);
                emit(p00, p10, p11, 2, 1);
                emit(p00, p11, p01, 2, 1);
            }
        // Walls at y = b w between texels (i, b − 1) and (i, b), from corner (i, b) to (i + 1, b).
        for (int i = 0; i < m_rows; ++i)
            for (int b = 0; b <= m_cols; ++b) {
                const double below = height(i, b - 1), above = height(i, b);
                if (below == above) continue;
                // The solid lies on the taller texel's side; the wall faces the shorter one.
                wall(i, b, i + 1, b, std::min(below, above), std::max(below, above), 1, above > below ? -1 : 1, emit);
            }
        // Walls at x = a w between texels (a − 1, j) and (a, j), from corner (a, j) to (a, j + 1).
        for (int a = 0; a <= m_rows; ++a)
            for (int j = 0; j < m_cols; ++j) {
                const double below = height(a - 1, j), above = height(a, j);
                if (below == above) continue;
                wall(a, j, a, j + 1, std::min(below, above), std::max(below, above), 0, above > below ? -1 : 1, emit);
            }
        // The bottom: a fan from its centre to every boundary corner, so each side wall's bottom
        // edge is one of its edges.
        const Vertex centre{static_cast<float>(0.5 * m_rows * m_texel_um), static_cast<float>(0.5 * m_cols * m_texel_um),
                            static_cast<float>(m_z_base)};
        auto boundary = [&](int a0, int b0, int a1, int b1) {
            emit(centre, vertex(a0, b0, m_z_base), vertex(a1, b1, m_z_base), 2, -1);
        };
        for (int a = 0; a < m_rows; ++a) {
            boundary(a, 0, a + 1, 0);
            boundary(a, m_cols, a + 1, m_cols);
        }
        for (int b = 0; b < m_cols; ++b) {
            boundary(0, b, 0, b + 1);
            boundary(m_rows, b, m_rows, b + 1);
        }
    }

private:
    double height(int i, int j) const {
        if (i < 0 || j < 0 || i >= m_rows || j >= m_cols) return m_z_base;
        return m_heights[static_cast<std::size_t>(i) * static_cast<std::size_t>(m_cols) + static_cast<std::size_t>(j)];
    }

    // Corner (a, b) is the point x = a w, y = b w; the same corner and height always give the
    // same floats, so triangles meeting there share the vertex exactly.
    Vertex vertex(int a, int b, double z) const {
        return {static_cast<float>(a * m_texel_um), static_cast<float>(b * m_texel_um), static_cast<float>(z)};
    }

    // The distinct heights in [lo, hi] of the (up to four) texels meeting at corner (a, b),
    // ascending: the vertices of the vertical line there that any wall uses.
    int corner_chain(int a, int b, double lo, double hi, std::array<double, 4>& chain) const {
        std::array<double, 4> around = {height(a - 1, b - 1), height(a - 1, b), height(a, b - 1), height(a, b)};
        std::sort(around.begin(), around.end());
        int n = 0;
        for (double z : around)
            if (z >= lo && z <= hi && (n == 0 || z != chain[static_cast<std::size_t>(n - 1)]))
                chain[static_cast<std::size_t>(n++)] = z;
        return n;
    }

    // A vertical wall between corners (a0, b0) and (a1, b1) from lo to hi, split at every height
    // meeting at either corner, triangulated as a zipper between the two vertical chains (each
    // triangle has vertices on both lines, so none is degenerate).
    template <typename Emit>
    void wall(int a0, int b0, int a1, int b1, double lo, double hi, int axis, int sign, Emit&& emit) const {
        std::array<double, 4> p{}, q{};
        const int m = corner_chain(a0, b0, lo, hi, p) - 1;
        const int n = corner_chain(a1, b1, lo, hi, q) - 1;
        int i = 0, j = 0;
        while (i < m || j < n) {
            const auto pi = static_cast<std::size_t>(i), qj = static_cast<std::size_t>(j);
            if (i < m && (j == n || p[pi + 1] <= q[qj + 1])) {
                emit(vertex(a0, b0, p[pi]), vertex(a1, b1, q[qj]), vertex(a0, b0, p[pi + 1]), axis, sign);
                ++i;
            } else {
                emit(vertex(a0, b0, p[pi]), vertex(a1, b1, q[qj]), vertex(a1, b1, q[qj + 1]), axis, sign);
                ++j;
            }
        }
    }

    const std::vector<double>& m_heights;
    int m_rows, m_cols;
    double m_texel_um;
    double m_z_base = 0.0;
};

void check_stl_input(const std::vector<double>& heights_um, int rows, int cols, double base_um, const char* what) {
    check_size(rows, cols, heights_um.size(), what);
    check_finite_heights(heights_um, cols, what);
    if (!(std::isfinite(base_um) && base_um > 0.0 && base_um <= 1e6))
        throw std::invalid_argument(std::string(what) + ": base_um " + full_precision(base_um) +
                                    " must be finite, > 0 and at most 1e6");
}

void put_u32(std::vector<char>& out, std::uint32_t value) {
    for (int k = 0; k < 4; ++k) out.push_back(static_cast<char>((value >> (8 * k)) & 0xffu));
}

void put_float(std::vector<char>& out, float value) {
    std::uint32_t bits = 0;
    std::memcpy(&bits, &value, sizeof bits);
    put_u32(out, bits);
}

}  // namespace

void write_heights_png16(const std::string& path, const std::vector<double>& heights_um, int rows, int cols,
                         double height_range_um, double texel_um) {
    const char* what = "heights PNG";
    check_size(rows, cols, heights_um.size(), what);
    check_range(height_range_um, what);
    check_texel(texel_um, what);
    check_finite_heights(heights_um, cols, what);
    const double tolerance = 1e-9 * height_range_um;
    for (std::size_t k = 0; k < heights_um.size(); ++k)
        if (heights_um[k] < -tolerance || heights_um[k] > height_range_um + tolerance)
            throw std::invalid_argument(std::string(what) + ": height " + full_precision(heights_um[k]) + " um at texel (" +
                                        std::to_string(k / static_cast<std::size_t>(cols)) + ", " +
                                        std::to_string(k % static_cast<std::size_t>(cols)) + ") is outside 0 ... " +
                                        full_precision(height_range_um) + " um");
    const std::vector<std::pair<std::string, std::string>> texts = {
        {"wavebrdf:height_range_um", full_precision(height_range_um)},
        {"wavebrdf:texel_um", full_precision(texel_um)},
        {"wavebrdf:units", "height in um = value / 65535 * height_range_um"},
        {"Software", std::string("wavebrdf ") + k_version},
    };
    write_grey_png(path, rows, cols, 16, texts, texel_um, [&](png_uint_32 i, png_bytep row) {
        const double* h = heights_um.data() + static_cast<std::size_t>(i) * static_cast<std::size_t>(cols);
        for (int j = 0; j < cols; ++j) {
            const double t = std::clamp(h[j] / height_range_um, 0.0, 1.0);
            const auto value = static_cast<std::uint32_t>(std::lround(t * 65535.0));
            row[2 * j] = static_cast<png_byte>(value >> 8);  // PNG is big-endian
            row[2 * j + 1] = static_cast<png_byte>(value & 0xffu);
        }
    });
}

int level_mask_count(int levels) {
    if (levels < 2 || levels > k_max_fabrication_levels)
        throw std::invalid_argument("levels " + std::to_string(levels) + " is outside 2 ... " +
                                    std::to_string(k_max_fabrication_levels));
    if ((levels & (levels - 1)) == 0) {
        int masks = 0;
        while ((1 << masks) < levels) ++masks;
        return masks;
    }
    return levels - 1;
}

std::vector<LevelMask> write_level_masks(const std::string& prefix, const std::vector<int>& level_index, int rows,
                                         int cols, int levels, double height_range_um, double texel_um) {
    const char* what = "level masks";
    check_size(rows, cols, level_index.size(), what);
    const int n_masks = level_mask_count(levels);
    check_range(height_range_um, what);
    check_texel(texel_um, what);
    for (std::size_t k = 0; k < level_index.size(); ++k)
        if (level_index[k] < 0 || level_index[k] >= levels)
            throw std::invalid_argument(std::string(what) + ": level " + std::to_string(level_index[k]) +
                                        " at texel (" + std::to_string(k / static_cast<std::size_t>(cols)) + ", " +
                                        std::to_string(k % static_cast<std::size_t>(cols)) + ") is outside 0 ... " +
                                        std::to_string(levels - 1));
    const bool binary = (levels & (levels - 1)) == 0;
    const double step_um = height_range_um / (levels - 1);
    std::vector<LevelMask> masks;
    for (int m = 0; m < n_masks; ++m) {
        char suffix[32];
        std::snprintf(suffix, sizeof suffix, "_%02d.png", m + 1);
        LevelMask mask;
        mask.path = prefix + suffix;
        mask.weight = binary ? (1 << m) : 1;
        mask.depth_um = mask.weight * step_um;
        // Exposed (1) where this step etches: bit m of the etch count (binary-weighted), or an
        // etch count of at least m + 1 (cumulative).
        auto exposed = [&](int level) {
            const int etch = levels - 1 - level;
            return binary ? ((etch >> m) & 1) != 0 : etch >= m + 1;
        };
        const std::vector<std::pair<std::string, std::string>> texts = {
            {"wavebrdf:mask", std::to_string(m + 1) + " of " + std::to_string(n_masks)},
            {"wavebrdf:depth_um", full_precision(mask.depth_um)},
            {"wavebrdf:texel_um", full_precision(texel_um)},
            {"wavebrdf:units", "white (1) = exposed, etched depth_um deep; black (0) = protected"},
            {"Software", std::string("wavebrdf ") + k_version},
        };
        write_grey_png(mask.path, rows, cols, 1, texts, texel_um, [&](png_uint_32 i, png_bytep row) {
            const int* level = level_index.data() + static_cast<std::size_t>(i) * static_cast<std::size_t>(cols);
            std::memset(row, 0, (static_cast<std::size_t>(cols) + 7) / 8);
            for (int j = 0; j < cols; ++j)
                if (exposed(level[j])) row[j / 8] = static_cast<png_byte>(row[j / 8] | (0x80u >> (j % 8)));
        });
        masks.push_back(mask);
    }
    nlohmann::json doc;
    doc["levels"] = levels;
    doc["step_um"] = step_um;
    doc["height_range_um"] = height_range_um;
    doc["texel_um"] = texel_um;
    doc["rows"] = rows;
    doc["cols"] = cols;
    doc["encoding"] = binary ? "binary-weighted" : "cumulative";
    doc["process"] =
        "start from a flat plate at the top height (level levels-1, height_range_um); apply the masks in order, "
        "etching the exposed (white) texels depth_um deep; a texel of level k ends at height k * step_um, having "
        "lost (levels-1-k) * step_um, the sum of depth_um over the masks exposing it";
    doc["pixel"] = "mask pixel (i, j) is texel (i, j) of heights.png: row i along x, column j along y";
    doc["masks"] = nlohmann::json::array();
    for (const LevelMask& mask : masks)
        doc["masks"].push_back({{"file", std::filesystem::path(mask.path).filename().string()},
                                {"depth_um", mask.depth_um},
                                {"weight", mask.weight}});
    doc["made_by"] = std::string("wavebrdf ") + k_version;
    write_text_atomically(prefix + ".json", doc.dump(2) + "\n");
    return masks;
}

long long stl_triangle_count(const std::vector<double>& heights_um, int rows, int cols, double base_um) {
    check_stl_input(heights_um, rows, cols, base_um, "STL");
    const ReliefSolid solid(heights_um, rows, cols, 1.0, base_um);
    long long count = 0;
    solid.triangles([&](const Vertex&, const Vertex&, const Vertex&, int, int) { ++count; });
    return count;
}

void write_stl(const std::string& path, const std::vector<double>& heights_um, int rows, int cols, double texel_um,
               double base_um) {
    const char* what = "STL";
    check_texel(texel_um, what);
    const long long count = stl_triangle_count(heights_um, rows, cols, base_um);
    if (count > static_cast<long long>(std::numeric_limits<std::uint32_t>::max()))
        throw std::invalid_argument(std::string(what) + ": the relief needs " + std::to_string(count) +
                                    " triangles, more than binary STL's 4294967295");
    const ReliefSolid solid(heights_um, rows, cols, texel_um, base_um);
    write_file_atomically(path, [&](const std::string& tmp) {
        FILE* file = std::fopen(tmp.c_str(), "wb");
        if (file == nullptr) throw std::runtime_error("cannot create " + tmp + ": " + std::strerror(errno));
        std::vector<char> buffer;
        buffer.reserve(1 << 20);
        bool failed = false;
        auto flush = [&] {
            if (!buffer.empty() && std::fwrite(buffer.data(), 1, buffer.size(), file) != buffer.size()) failed = true;
            buffer.clear();
        };
        // The header must not begin with "solid", or readers take the file for ASCII STL.
        std::string header = "wavebrdf " + std::string(k_version) + " texel relief, units um, texel_um " +
                             full_precision(texel_um) + ", base z " + full_precision(solid.z_base());
        header.resize(80, ' ');
        buffer.insert(buffer.end(), header.begin(), header.end());
        put_u32(buffer, static_cast<std::uint32_t>(count));
        solid.triangles([&](Vertex a, Vertex b, Vertex c, int axis, int sign) {
            // Wind counter-clockwise seen from outside: the cross product along the outward axis.
            const double u[3] = {double(b.x) - double(a.x), double(b.y) - double(a.y), double(b.z) - double(a.z)};
            const double v[3] = {double(c.x) - double(a.x), double(c.y) - double(a.y), double(c.z) - double(a.z)};
            const double cross[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
            if (cross[axis] * sign < 0) std::swap(b, c);
            float normal[3] = {0.0f, 0.0f, 0.0f};
            normal[axis] = static_cast<float>(sign);
            for (float value : normal) put_float(buffer, value);
            for (const Vertex& p : {a, b, c}) {
                put_float(buffer, p.x);
                put_float(buffer, p.y);
                put_float(buffer, p.z);
            }
            buffer.push_back(0);
            buffer.push_back(0);
            if (buffer.size() >= (1u << 20) - 64) flush();
        });
        flush();
        const bool write_error = failed || std::ferror(file) != 0;
        const bool close_error = std::fclose(file) != 0;
        if (write_error || close_error) throw std::runtime_error("cannot write " + tmp + ": " + std::strerror(errno));
    });
}

FabricationFiles write_fabrication_exports(const std::string& out_dir, const std::vector<double>& heights_um, int rows,
                                           int cols, double texel_um, double height_range_um, int levels,
                                           double max_stl_bytes) {
    const char* what = "fabrication exports";
    check_size(rows, cols, heights_um.size(), what);
    check_range(height_range_um, what);
    check_texel(texel_um, what);
    check_finite_heights(heights_um, cols, what);
    std::vector<int> level_index;
    if (levels != 0) {
        level_mask_count(levels);  // validates levels
        const double step_um = height_range_um / (levels - 1);
        level_index.resize(heights_um.size());
        for (std::size_t k = 0; k < heights_um.size(); ++k) {
            const double k_level = std::round(heights_um[k] / step_um);
            if (k_level < 0 || k_level > levels - 1 || std::abs(heights_um[k] - k_level * step_um) > 1e-6 * step_um)
                throw std::invalid_argument(std::string(what) + ": height " + full_precision(heights_um[k]) + " um at texel (" +
                                            std::to_string(k / static_cast<std::size_t>(cols)) + ", " +
                                            std::to_string(k % static_cast<std::size_t>(cols)) + ") is not one of the " +
                                            std::to_string(levels) + " levels k * " + full_precision(step_um) + " um");
            level_index[k] = static_cast<int>(k_level);
        }
    }
    const std::filesystem::path dir(out_dir);
    FabricationFiles files;
    files.heights_png = (dir / "heights.png").string();
    write_heights_png16(files.heights_png, heights_um, rows, cols, height_range_um, texel_um);
    if (levels != 0) {
        files.masks = write_level_masks((dir / "masks").string(), level_index, rows, cols, levels, height_range_um,
                                        texel_um);
        files.masks_json = (dir / "masks.json").string();
    }
    // The heights as x3p for metrology and mask-writer tools that read ISO 25178 surfaces.
    const double x3p_bytes = 24.0 * static_cast<double>(heights_um.size());
    if (x3p_bytes > max_stl_bytes) {
        files.x3p_note = "heights.x3p not written: its copies take " + full_precision(x3p_bytes / 1e9) +
                         " GB, over the limit of " + full_precision(max_stl_bytes / 1e9) + " GB";
    } else {
        try {
            std::vector<double> values(heights_um.size());
            for (std::size_t k = 0; k < values.size(); ++k) values[k] = heights_um[k] / texel_um;
            const Heightfield hf(rows, cols, std::move(values), texel_um, 1.0);
            write_surface((dir / "heights.x3p").string(), from_heightfield(hf, "x3p"));
            files.heights_x3p = (dir / "heights.x3p").string();
        } catch (const std::runtime_error& e) {
            // The plugin did not load (or could not write): the other files do not depend on it.
            files.x3p_note = std::string("heights.x3p not written: ") + e.what();
        }
    }
    const double base_um = std::max(height_range_um, texel_um);
    files.stl_triangles = stl_triangle_count(heights_um, rows, cols, base_um);
    const double stl_bytes = 84.0 + 50.0 * double(files.stl_triangles);
    if (stl_bytes > max_stl_bytes) {
        files.note = "heights.stl not written: " + std::to_string(files.stl_triangles) + " triangles, " +
                     full_precision(stl_bytes / 1e9) + " GB, exceed the limit of " + full_precision(max_stl_bytes / 1e9) + " GB";
        return files;
    }
    files.heights_stl = (dir / "heights.stl").string();
    write_stl(files.heights_stl, heights_um, rows, cols, texel_um, base_um);
    return files;
}

}  // namespace wavebrdf
