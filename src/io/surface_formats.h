#pragma once
// The readers and writers behind wavebrdf/surface_file.h, one file per format, and the
// bounds-checked byte access they share. Every reader takes the whole file in memory and its
// name for messages; every offset and size is checked against the bytes before it is used.
#include <cmath>
#include <cstdint>
#include <cstring>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "wavebrdf/io.h"
#include "wavebrdf/surface_file.h"

namespace wavebrdf::surface_io {

// Throws std::runtime_error "<name>: <what>".
[[noreturn]] inline void fail(const std::string& name, const std::string& what) {
    throw std::runtime_error(name + ": " + what);
}

// Little- or big-endian reads at an offset, refused past the end ("truncated").
class Bytes {
public:
    Bytes(const std::string& data, const std::string& name) : m_data(data), m_name(name) {}
    std::size_t size() const { return m_data.size(); }
    const std::string& name() const { return m_name; }
    const std::string& data() const { return m_data; }

    void need(std::size_t offset, std::size_t count, const char* what) const {
        if (offset > m_data.size() || count > m_data.size() - offset)
            fail(m_name, std::string("is truncated: ") + what + " needs bytes " + std::to_string(offset) + " to " +
                             std::to_string(static_cast<unsigned long long>(offset) + count) + " of " +
                             std::to_string(m_data.size()));
    }
    template <typename T>
    T get(std::size_t offset, bool big_endian = false, const char* what = "a header field") const {
        need(offset, sizeof(T), what);
        unsigned char b[sizeof(T)];
        std::memcpy(b, m_data.data() + offset, sizeof(T));
        if (big_endian)
            for (std::size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(b[i], b[sizeof(T) - 1 - i]);
        T value;
        std::memcpy(&value, b, sizeof(T));
        return value;
    }
    // `count` bytes at `offset` as text, cut at the first NUL, trailing blanks removed.
    std::string text(std::size_t offset, std::size_t count) const {
        need(offset, count, "a text field");
        std::string s(m_data.data() + offset, count);
        const std::size_t nul = s.find('\0');
        if (nul != std::string::npos) s.resize(nul);
        while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r' || s.back() == '\n'))
            s.pop_back();
        return s;
    }

private:
    const std::string& m_data;
    std::string m_name;
};

// Element types the binary layouts use.
enum class Sample { i8, u8, i16, u16, i32, u32, i64, f32, f64 };
std::size_t sample_size(Sample type);
// Value of one sample at `p` (no bounds check: callers check the whole block first).
double sample_value(const char* p, Sample type, bool big_endian);

// Refuses a grid of rows × cols (each side 1 … k_max_surface_side, the product at most
// k_max_surface_points) and, when bytes_per_point > 0, one whose data would need more than
// `available` bytes; the message names the declared size.
void check_grid(const std::string& name, long long rows, long long cols, std::size_t bytes_per_point = 0,
                std::size_t available = 0);
// Refuses a spacing that is not finite and > 0 (`what`: "dx", "dy").
double check_spacing(const std::string& name, double spacing_um, const char* what);

// The readers: every one returns a surface with rows, cols, spacing, heights and format set.
MeasuredSurface read_npy(const Bytes& bytes, std::optional<double> spacing_um);
MeasuredSurface read_text(const Bytes& bytes, std::optional<double> spacing_um);
MeasuredSurface read_x3p(const Bytes& bytes);
MeasuredSurface read_sdf(const Bytes& bytes);
MeasuredSurface read_datx(const Bytes& bytes);
MeasuredSurface read_metropro(const Bytes& bytes);
MeasuredSurface read_sur(const Bytes& bytes);
MeasuredSurface read_plu(const Bytes& bytes);
MeasuredSurface read_al3d(const Bytes& bytes);

// The writers: the file's bytes.
std::string npy_bytes(const MeasuredSurface& surface);
std::string x3p_bytes(const MeasuredSurface& surface);
std::string sdf_bytes(const MeasuredSurface& surface);

// True for bytes that look like each format (detect_surface_format asks them in turn).
bool looks_like_plu(const std::string& bytes);
bool looks_like_text(const std::string& bytes);

// The heightfield readers of io.h take measured surfaces too: a file that exists, is not an
// OpenEXR file and is either of a recognised binary format or not named .exr (a text file named
// .exr is left to OpenEXR's error).
bool is_measured_surface_file(const std::string& path);
// What a measured surface says as a heightfield: texel_um its spacing when square (none for
// npy and text, which state none), vscale none (1), units and made_by describing it.
HeightfieldAttributes measured_attributes(const std::string& path);
// True for a measured surface that states no spacing (npy, a text matrix without a header):
// resolve_heightfield_scale (io.h) then refuses to fall back to a default texel width.
bool measured_surface_needs_spacing(const std::string& path);
// The measured surface as a heightfield (to_heightfield), spacing = texel_um for npy and text.
HeightfieldFile read_measured_heightfield(const std::string& path, std::optional<double> texel_um,
                                          std::optional<double> vscale);

// MD5 of `data` as 32 lowercase hex digits (RFC 1321), for x3p's data checksum.
std::string md5_hex(const std::string& data);

}  // namespace wavebrdf::surface_io
