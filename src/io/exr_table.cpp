// The BRDF table's file (table.h): one single-part RGB float EXR, a mosaic of the light grid's
// slices, with the axes and the query in wavebrdf:* header attributes (docs/table.md).
//
// Why a mosaic rather than EXR layers: 32 × 32 lights would be 3072 channels, beyond what our
// reader accepts (k_max_exr_channels = 64, io.h) and what viewers show; a mosaic is one image
// any EXR viewer opens, and its tiles are indexed by the light grid's attributes.
#include <algorithm>
#include <utility>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <stdexcept>
#include <string>

#include <ImfDoubleAttribute.h>
#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfIntAttribute.h>
#include <ImfOutputFile.h>
#include <ImfStringAttribute.h>

#include "io/exr_source.h"
#include "io/exr_threads.h"
#include "wavebrdf/io.h"
#include "wavebrdf/memory.h"
#include "wavebrdf/spectrum.h"
#include "wavebrdf/table.h"
#include "wavebrdf/text.h"

namespace wavebrdf {

namespace {

constexpr const char* k_kind = "wavebrdf brdf table";
constexpr const char* k_unit = "f_r in 1/sr (BRDF); one wavelength: R = G = B; several: CIE 1931 to linear sRGB";
constexpr const char* k_omega_o =
    "tile pixel (p, q) of n x n: omega_o = ((p + 0.5) / n * 2 - 1, (q + 0.5) / n * 2 - 1), projected outgoing "
    "direction; 0 outside the unit disk";
constexpr const char* k_light_grid =
    "tile (a, b) of rows x cols: omega_i = (max_sin * ((a + 0.5) / rows * 2 - 1), max_sin * ((b + 0.5) / cols * 2 - "
    "1)), projected direction towards the light; tiles with |omega_i| > max_sin are 0 (not rendered)";
constexpr const char* k_layout = "mosaic: image row a * n + p, column b * n + q holds tile (a, b), pixel (p, q)";

std::string join(const std::vector<double>& values) {
    std::string s;
    for (std::size_t i = 0; i < values.size(); ++i) s += (i ? "," : "") + format_shortest(values[i]);
    return s;
}

[[noreturn]] void table_fail(const std::string& path, const std::string& what) {
    throw std::runtime_error(path + ": " + what);
}

// Reads typed attributes of a table file's header; every error names the file and attribute.
class Attributes {
public:
    Attributes(const std::string& path, const Imf::Header& header) : m_path(path), m_header(header) {}

    std::string text(const std::string& name, std::size_t max_length = 4096) const {
        const auto* a = m_header.findTypedAttribute<Imf::StringAttribute>(name);
        if (a == nullptr) missing(name, "string");
        if (a->value().size() > max_length)
            table_fail(m_path, "attribute " + name + " is " + std::to_string(a->value().size()) +
                             " bytes long; expected at most " + std::to_string(max_length));
        return a->value();
    }
    double real(const std::string& name) const {
        const auto* a = m_header.findTypedAttribute<Imf::DoubleAttribute>(name);
        if (a == nullptr) missing(name, "double");
        if (!std::isfinite(a->value()))
            table_fail(m_path, "attribute " + name + " = " + format_shortest(a->value()) + " is not finite");
        return a->value();
    }
    int integer(const std::string& name, int lo, int hi) const {
        const auto* a = m_header.findTypedAttribute<Imf::IntAttribute>(name);
        if (a == nullptr) missing(name, "int");
        if (a->value() < lo || a->value() > hi)
            table_fail(m_path, "attribute " + name + " = " + std::to_string(a->value()) + " is out of range; expected " +
                             std::to_string(lo) + " to " + std::to_string(hi));
        return a->value();
    }
    // A comma-separated list of at most `max_count` numbers (format_shortest, so exact).
    std::vector<double> reals(const std::string& name, std::size_t max_count) const {
        const std::string s = text(name, max_count * 32);
        std::vector<double> values;
        std::size_t at = 0;
        while (at <= s.size()) {
            const std::size_t comma = std::min(s.find(',', at), s.size());
            const std::string item = s.substr(at, comma - at);
            char* end = nullptr;
            const double v = std::strtod(item.c_str(), &end);
            if (item.empty() || end != item.c_str() + item.size() || !std::isfinite(v))
                table_fail(m_path, "attribute " + name + " has '" + item + "'; expected finite numbers separated by commas");
            if (values.size() >= max_count)
                table_fail(m_path, "attribute " + name + " lists more than " + std::to_string(max_count) + " numbers");
            values.push_back(v);
            at = comma + 1;
        }
        return values;
    }

private:
    [[noreturn]] void missing(const std::string& name, const char* type) const {
        table_fail(m_path, "has no " + std::string(type) + " attribute " + name +
                         "; expected a BRDF table written by wavebrdf table (docs/table.md)");
    }
    const std::string& m_path;
    const Imf::Header& m_header;
};

void check_sizes(const BrdfTable& t) {
    const TableSpec& s = t.spec;
    const std::size_t n = std::size_t(s.resolution), rows = std::size_t(s.lights.rows),
                      cols = std::size_t(s.lights.cols);
    if (t.values.size() != rows * cols * n * n * 3 || t.light_x.size() != rows || t.light_y.size() != cols ||
        t.rendered.size() != rows * cols)
        throw std::invalid_argument("table has " + std::to_string(t.values.size()) + " values for " +
                                    std::to_string(rows) + "x" + std::to_string(cols) + " lights of " +
                                    std::to_string(n) + "x" + std::to_string(n) +
                                    " slices; expected rows * cols * n * n * 3 values and matching light axes");
}

}  // namespace

std::vector<float> table_mosaic(const BrdfTable& table) {
    check_sizes(table);
    const std::size_t n = std::size_t(table.spec.resolution), rows = std::size_t(table.spec.lights.rows),
                      cols = std::size_t(table.spec.lights.cols);
    std::vector<float> mosaic(table.values.size());
    const std::size_t width = cols * n;
    for (std::size_t a = 0; a < rows; ++a)
        for (std::size_t b = 0; b < cols; ++b)
            for (std::size_t p = 0; p < n; ++p) {
                const float* from = table.values.data() + (((a * cols + b) * n + p) * n) * 3;
                std::copy(from, from + n * 3, mosaic.begin() + std::ptrdiff_t(((a * n + p) * width + b * n) * 3));
            }
    return mosaic;
}

void write_brdf_table(const std::string& path, const BrdfTable& table) {
    validate(table.spec);
    const std::vector<float> mosaic = table_mosaic(table);
    const TableSpec& s = table.spec;
    const int height = s.lights.rows * s.resolution, width = s.lights.cols * s.resolution;
    Imf::Header header(width, height);  // width = columns, height = rows
    for (const char* c : {"R", "G", "B"}) header.channels().insert(c, Imf::Channel(Imf::FLOAT));
    header.insert("wavebrdf:kind", Imf::StringAttribute(k_kind));
    header.insert("wavebrdf:version", Imf::StringAttribute(table.version));
    header.insert("wavebrdf:unit", Imf::StringAttribute(k_unit));
    header.insert("wavebrdf:layout", Imf::StringAttribute(k_layout));
    header.insert("wavebrdf:omega_o", Imf::StringAttribute(k_omega_o));
    header.insert("wavebrdf:light_grid", Imf::StringAttribute(k_light_grid));
    header.insert("wavebrdf:light_rows", Imf::IntAttribute(s.lights.rows));
    header.insert("wavebrdf:light_cols", Imf::IntAttribute(s.lights.cols));
    header.insert("wavebrdf:light_max_sin", Imf::DoubleAttribute(s.lights.max_sin));
    header.insert("wavebrdf:light_x", Imf::StringAttribute(join(table.light_x)));
    header.insert("wavebrdf:light_y", Imf::StringAttribute(join(table.light_y)));
    header.insert("wavebrdf:resolution", Imf::IntAttribute(s.resolution));
    header.insert("wavebrdf:model", Imf::StringAttribute(to_string(s.query.model)));
    header.insert("wavebrdf:x_um", Imf::DoubleAttribute(s.query.x_um));
    header.insert("wavebrdf:y_um", Imf::DoubleAttribute(s.query.y_um));
    header.insert("wavebrdf:sigma_p_um", Imf::DoubleAttribute(s.query.sigma_p_um));
    header.insert("wavebrdf:lambdas_um", Imf::StringAttribute(join(s.lambdas_um)));
    header.insert("wavebrdf:spectral", Imf::IntAttribute(s.spectral ? 1 : 0));
    header.insert("wavebrdf:precision", Imf::StringAttribute(s.double_precision ? "double" : "float"));
    header.insert("wavebrdf:heightfield_rows", Imf::IntAttribute(table.heightfield_rows));
    header.insert("wavebrdf:heightfield_cols", Imf::IntAttribute(table.heightfield_cols));
    header.insert("wavebrdf:texel_um", Imf::DoubleAttribute(table.texel_um));
    header.insert("wavebrdf:vscale", Imf::DoubleAttribute(table.vscale));
    if (!table.source.empty())
        header.insert("wavebrdf:source", Imf::StringAttribute(table.source.substr(0, k_max_attribute_chars)));
    // As the slices (src/io/io.cpp): ZIP at deflate's fastest level, lossless.
    header.zipCompressionLevel() = 1;
    write_file_atomically(path, [&](const std::string& temporary) {
        Imf::FrameBuffer frame;
        const std::size_t stride = 3 * sizeof(float);
        for (std::size_t c = 0; c < 3; ++c)
            frame.insert(std::string(1, "RGB"[c]),
                         Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(const_cast<float*>(mosaic.data() + c)), stride,
                                    stride * static_cast<std::size_t>(width)));
        Imf::OutputFile out(temporary.c_str(), header, detail::exr_threads());
        out.setFrameBuffer(frame);
        out.writePixels(height);
    });
}

BrdfTable read_brdf_table(const std::string& path) {
    // The header first (ExrSource: its raw walk bounds attribute sizes, the image size, channels
    // and tiles before OpenEXR allocates anything, refuses multi-part files and pixel data larger
    // than the file can hold), then the attributes: a file that is not a table is refused before
    // a pixel is allocated or read.
    const detail::ExrSource source(path);
    BrdfTable t;
    try {
        const Attributes at(path, source.header());
        const std::string kind = at.text("wavebrdf:kind");
        if (kind != k_kind) table_fail(path, "attribute wavebrdf:kind is '" + kind + "'; expected '" + k_kind + "'");
        t.version = at.text("wavebrdf:version", 256);
        // The conventions the values follow: every one required, and the one this build writes.
        const std::pair<const char*, const char*> conventions[] = {{"wavebrdf:unit", k_unit},
                                                                   {"wavebrdf:layout", k_layout},
                                                                   {"wavebrdf:omega_o", k_omega_o},
                                                                   {"wavebrdf:light_grid", k_light_grid}};
        for (const auto& [name, expected] : conventions)
            if (at.text(name, 1024) != expected)
                table_fail(path, std::string("attribute ") + name +
                               " differs from this build's convention; expected a table written by wavebrdf table "
                               "(docs/table.md)");
        TableSpec& s = t.spec;
        s.resolution = at.integer("wavebrdf:resolution", 1, 8192);
        const int max_lights = int(k_max_table_side);
        s.lights.rows = at.integer("wavebrdf:light_rows", 1, max_lights);
        s.lights.cols = at.integer("wavebrdf:light_cols", 1, max_lights);
        s.lights.max_sin = at.real("wavebrdf:light_max_sin");
        s.query.model = parse_model(at.text("wavebrdf:model", 64));
        s.query.x_um = at.real("wavebrdf:x_um");
        s.query.y_um = at.real("wavebrdf:y_um");
        s.query.sigma_p_um = at.real("wavebrdf:sigma_p_um");
        s.lambdas_um = at.reals("wavebrdf:lambdas_um", 256);
        s.spectral = at.integer("wavebrdf:spectral", 0, 1) == 1;
        const std::string precision = at.text("wavebrdf:precision", 16);
        if (precision != "float" && precision != "double")
            table_fail(path, "attribute wavebrdf:precision is '" + precision + "'; expected 'float' or 'double'");
        s.double_precision = precision == "double";
        // The surface it was rendered from: the bounds of a heightfield (io.h, heightfield.h).
        t.heightfield_rows = at.integer("wavebrdf:heightfield_rows", 1, 65536);
        t.heightfield_cols = at.integer("wavebrdf:heightfield_cols", 1, 65536);
        t.texel_um = at.real("wavebrdf:texel_um");
        if (!(t.texel_um >= 1e-4 && t.texel_um <= 1e4))
            table_fail(path, "attribute wavebrdf:texel_um = " + format_shortest(t.texel_um) +
                           " is out of range; expected 1e-4 to 1e4 um");
        t.vscale = at.real("wavebrdf:vscale");
        if (std::abs(t.vscale) > 1e4)
            table_fail(path,
                 "attribute wavebrdf:vscale = " + format_shortest(t.vscale) + " is out of range; expected |v| <= 1e4");
        // The footprint's limit for this surface (brdf.h validate: at most 10 tile periods).
        const double period = t.texel_um * double(std::max(t.heightfield_rows, t.heightfield_cols));
        if (s.query.sigma_p_um > 10.0 * period)
            table_fail(path, "attribute wavebrdf:sigma_p_um = " + format_shortest(s.query.sigma_p_um) +
                           " um is more than 10 periods of the " + std::to_string(t.heightfield_rows) + "x" +
                           std::to_string(t.heightfield_cols) + " surface of texel " + format_shortest(t.texel_um) +
                           " um (" + format_shortest(period) + " um); expected the table of a real render");
        if (source.header().findTypedAttribute<Imf::StringAttribute>("wavebrdf:source") != nullptr)
            t.source = at.text("wavebrdf:source", k_max_attribute_chars);
        try {
            validate(s);
        } catch (const std::exception& e) {
            table_fail(path, std::string("attributes describe an invalid table: ") + e.what());
        }
        const long long height = static_cast<long long>(s.lights.rows) * s.resolution;
        const long long width = static_cast<long long>(s.lights.cols) * s.resolution;
        if (source.m_rows != height || source.m_cols != width)
            table_fail(path, "mosaic is " + std::to_string(source.m_rows) + "x" + std::to_string(source.m_cols) +
                           " pixels but the attributes declare " + std::to_string(s.lights.rows) + "x" +
                           std::to_string(s.lights.cols) + " lights of " + std::to_string(s.resolution) + "x" +
                           std::to_string(s.resolution) + " (" + std::to_string(height) + "x" + std::to_string(width) +
                           "); expected them to agree");
        light_grid_axes(s.lights, t.light_x, t.light_y, t.rendered);
        const std::vector<double> light_x = at.reals("wavebrdf:light_x", std::size_t(s.lights.rows));
        const std::vector<double> light_y = at.reals("wavebrdf:light_y", std::size_t(s.lights.cols));
        if (light_x != t.light_x || light_y != t.light_y)
            table_fail(path,
                 "attributes wavebrdf:light_x/light_y disagree with the grid of wavebrdf:light_rows, "
                 "light_cols and light_max_sin; expected max_sin * ((a + 0.5) / rows * 2 - 1)");
    } catch (const std::runtime_error&) {
        throw;
    } catch (const std::exception& e) {
        table_fail(path, std::string("cannot read the table's attributes (") + e.what() + ")");
    }
    // The values once, read a row of lights (n mosaic rows) at a time into their place
    // (rows, cols, n, n, 3): the table's memory and one row of lights, not the mosaic twice.
    const std::size_t n = std::size_t(t.spec.resolution), rows = std::size_t(t.spec.lights.rows),
                      cols = std::size_t(t.spec.lights.cols), width = cols * n;
    const double values = double(rows) * double(width) * double(n) * 3.0;
    require_memory(4.0 * values + 4.0 * double(width) * double(n) * 3.0, memory_limit(0.0),
                   "the table " + path + " (" + std::to_string(rows) + "x" + std::to_string(cols) + " lights of " +
                       std::to_string(n) + "x" + std::to_string(n) + ")",
                   "more memory");
    const bool rgb = source.has_channel("R") && source.has_channel("G") && source.has_channel("B");
    if (!rgb && !source.has_channel("Y")) table_fail(path, "has no R, G, B channels (nor Y); expected an RGB image");
    t.values = allocating("the table's values", 4.0 * values,
                          [&] { return std::vector<float>(static_cast<std::size_t>(values)); });
    std::vector<float> band(width * n * 3);
    for (std::size_t a = 0; a < rows; ++a) {
        const int first = int(a * n), last = int(a * n + n - 1);
        if (rgb) {
            source.read_rows({"R", "G", "B"}, first, last, band.data());
        } else {  // a luminance-only file is grey: Y in every channel, as read_rgb_exr does
            source.read_rows("Y", first, last, band.data());
            for (std::size_t k = width * n; k-- > 0;) band[3 * k] = band[3 * k + 1] = band[3 * k + 2] = band[k];
        }
        for (float v : band)
            if (!std::isfinite(v)) table_fail(path, "has a value that is not finite; expected f_r values");
        for (std::size_t b = 0; b < cols; ++b)
            for (std::size_t p = 0; p < n; ++p) {
                const float* from = band.data() + (p * width + b * n) * 3;
                std::copy(from, from + n * 3, t.values.begin() + std::ptrdiff_t((((a * cols + b) * n + p) * n) * 3));
            }
    }
    return t;
}

}  // namespace wavebrdf
