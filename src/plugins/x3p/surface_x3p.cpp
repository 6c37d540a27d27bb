// ISO 25178-72 (ISO 5436-2 XML) x3p files: a zip archive holding main.xml (the description),
// the point data it links (bindata/data.bin, x fastest, little-endian), optionally a bit mask of
// valid points, and md5checksum.hex (the MD5 of main.xml). The zip is libzip's, the XML pugixml's.
#include <zip.h>

#include <chrono>
#include <cmath>
#include <ctime>
#include <limits>
#include <memory>
#include <pugixml.hpp>
#include <sstream>

#include "io/surface_formats.h"
#include "wavebrdf/text.h"
#include "wavebrdf/version.h"

namespace wavebrdf::surface_io {

namespace {

// main.xml and md5checksum.hex are small; refused over this (a zip bomb declares gigabytes).
constexpr zip_uint64_t k_max_xml_bytes = 16u << 20;

struct ZipArchive {
    zip_t* archive = nullptr;
    ~ZipArchive() {
        if (archive) zip_discard(archive);
    }
};

// Entry `index`'s first `count` bytes (count ≤ its declared size, checked by the caller).
std::string read_entry(const Bytes& b, zip_t* za, zip_uint64_t index, zip_uint64_t count, const std::string& entry) {
    zip_file_t* f = zip_fopen_index(za, index, 0);
    if (!f) fail(b.name(), "cannot open '" + entry + "' in the x3p archive: " + zip_strerror(za));
    std::string out(static_cast<std::size_t>(count), '\0');
    zip_uint64_t done = 0;
    while (done < count) {
        const zip_int64_t n = zip_fread(f, &out[done], count - done);
        if (n <= 0) {
            const std::string why = n < 0 ? zip_file_strerror(f) : "it ends early";
            zip_fclose(f);
            fail(b.name(), "cannot read '" + entry + "' in the x3p archive: " + why);
        }
        done += zip_uint64_t(n);
    }
    zip_fclose(f);
    return out;
}

std::string child_text(const pugi::xml_node& node, const char* path) {
    return node.first_element_by_path(path).text().as_string();
}

double number(const Bytes& b, const pugi::xml_node& node, const char* path, std::optional<double> fallback) {
    const pugi::xml_node n = node.first_element_by_path(path);
    std::string text = n.text().as_string();
    const std::size_t first = text.find_first_not_of(" \t\r\n");
    if (n.empty() || first == std::string::npos) {
        if (fallback) return *fallback;
        fail(b.name(), std::string("main.xml has no ") + path + "; expected a number there");
    }
    text = text.substr(first);
    char* stop = nullptr;
    const double v = std::strtod(text.c_str(), &stop);
    if (stop == text.c_str() || !std::isfinite(v))
        fail(b.name(), std::string("main.xml ") + path + " '" + text + "' is not a finite number");
    return v;
}

long long integer(const Bytes& b, const pugi::xml_node& node, const char* path) {
    const double v = number(b, node, path, std::nullopt);
    if (v != std::floor(v) || v < 0 || v > 1e12)
        fail(b.name(), std::string("main.xml ") + path + " = " + format_shortest(v) + "; expected a count");
    return static_cast<long long>(v);
}

std::string upper(std::string s) {
    for (char& c : s) c = char(std::toupper(static_cast<unsigned char>(c)));
    return s;
}

std::string trimmed(std::string s) {
    const std::size_t a = s.find_first_not_of(" \t\r\n");
    if (a == std::string::npos) return "";
    const std::size_t z = s.find_last_not_of(" \t\r\n");
    return s.substr(a, z - a + 1);
}

}  // namespace

MeasuredSurface read_x3p(const Bytes& b) {
    zip_error_t error;
    zip_error_init(&error);
    zip_source_t* source = zip_source_buffer_create(b.data().data(), b.size(), 0, &error);
    if (!source) fail(b.name(), std::string("cannot be read as a zip archive: ") + zip_error_strerror(&error));
    ZipArchive za;
    za.archive = zip_open_from_source(source, ZIP_RDONLY | ZIP_CHECKCONS, &error);
    if (!za.archive) {
        zip_source_free(source);
        const std::string why = zip_error_strerror(&error);
        zip_error_fini(&error);
        fail(b.name(), "is not a valid x3p (zip) archive: " + why);
    }
    zip_error_fini(&error);
    const zip_int64_t entries = zip_get_num_entries(za.archive, 0);
    if (entries < 0 || entries > 100000)
        fail(b.name(), "holds " + std::to_string(entries) + " zip entries; expected an x3p archive");
    // main.xml: at the top, or in one folder (archives zipped with their folder); never macOS's
    // resource copies under __MACOSX/.
    std::string prefix;
    zip_int64_t main_index = -1;
    for (zip_int64_t i = 0; i < entries; ++i) {
        const char* name = zip_get_name(za.archive, zip_uint64_t(i), 0);
        if (!name) continue;
        const std::string n = name;
        if (n.compare(0, 9, "__MACOSX/") == 0) continue;
        if (n == "main.xml" || (n.size() > 9 && n.compare(n.size() - 9, 9, "/main.xml") == 0)) {
            if (main_index < 0 || n.size() < prefix.size() + 8) {
                main_index = i;
                prefix = n.substr(0, n.size() - 8);
            }
        }
    }
    if (main_index < 0) fail(b.name(), "is a zip archive without main.xml; expected an x3p file (ISO 25178-72)");
    const auto entry = [&](const std::string& name, zip_uint64_t max_bytes, std::optional<zip_uint64_t> exact_prefix,
                           bool required) -> std::optional<std::string> {
        const zip_int64_t index = zip_name_locate(za.archive, name.c_str(), 0);
        if (index < 0) {
            if (required) fail(b.name(), "links '" + name + "', which the archive does not hold");
            return std::nullopt;
        }
        zip_stat_t st;
        zip_stat_init(&st);
        if (zip_stat_index(za.archive, zip_uint64_t(index), 0, &st) != 0 || !(st.valid & ZIP_STAT_SIZE))
            fail(b.name(), "cannot read the size of '" + name + "' in the archive");
        // Deflate expands at most 1032:1; an entry declaring more than that of its compressed
        // size lies, and is refused before anything of that size is allocated.
        if ((st.valid & ZIP_STAT_COMP_SIZE) && st.size / 1032 > st.comp_size + 1024)
            fail(b.name(), "'" + name + "' declares " + std::to_string(st.size) + " bytes from " +
                               std::to_string(st.comp_size) + " compressed; the archive is damaged");
        zip_uint64_t count = st.size;
        if (exact_prefix) {
            if (st.size < *exact_prefix)
                fail(b.name(), "'" + name + "' holds " + std::to_string(st.size) + " bytes; the declared points need " +
                                   std::to_string(*exact_prefix));
            count = *exact_prefix;
        } else if (st.size > max_bytes) {
            fail(b.name(), "'" + name + "' declares " + std::to_string(st.size) + " bytes; expected at most " +
                               std::to_string(max_bytes));
        }
        return read_entry(b, za.archive, zip_uint64_t(index), count, name);
    };

    const std::string xml = *entry(prefix + "main.xml", k_max_xml_bytes, std::nullopt, true);
    pugi::xml_document doc;
    const pugi::xml_parse_result parsed = doc.load_buffer(xml.data(), xml.size());
    if (!parsed) fail(b.name(), std::string("main.xml is not well-formed XML: ") + parsed.description());
    const pugi::xml_node root = doc.document_element();
    const std::string root_name = root.name();
    if (root_name.find("ISO5436") == std::string::npos)
        fail(b.name(), "main.xml's root is <" + root_name + ">; expected <ISO5436_2> (ISO 25178-72)");
    const pugi::xml_node r1 = root.child("Record1"), r3 = root.child("Record3");
    if (!r1 || !r3) fail(b.name(), "main.xml has no Record1 or Record3; expected an ISO 5436-2 description");
    const std::string feature = trimmed(child_text(r1, "FeatureType"));
    if (feature != "SUR")
        fail(b.name(), "is an x3p file of feature type '" + feature +
                           "'; only areal surfaces (SUR) are read, not profiles (PRF) or point clouds (PCL)");
    const pugi::xml_node axes = r1.child("Axes");
    for (const char* axis : {"CX", "CY"}) {
        const std::string type = trimmed(child_text(axes, (std::string(axis) + "/AxisType").c_str()));
        if (type != "I")
            fail(b.name(), std::string("has ") + axis + " axis type '" + type +
                               "'; only incremental (I) x and y axes are read, not point lists (A)");
    }
    const std::string z_type = trimmed(child_text(axes, "CZ/AxisType"));
    if (z_type != "A") fail(b.name(), "has CZ axis type '" + z_type + "'; expected absolute heights (A)");
    const std::string dtype = trimmed(child_text(axes, "CZ/DataType"));
    Sample type;
    if (dtype == "D") type = Sample::f64;
    else if (dtype == "F") type = Sample::f32;
    else if (dtype == "L") type = Sample::i32;
    else if (dtype == "I") type = Sample::i16;
    else fail(b.name(), "has CZ data type '" + dtype + "'; expected I, L, F or D");
    const double dx_m = number(b, axes, "CX/Increment", std::nullopt);
    const double dy_m = number(b, axes, "CY/Increment", std::nullopt);
    const double z_increment = number(b, axes, "CZ/Increment", 1.0);
    const double z_offset = number(b, axes, "CZ/Offset", 0.0);
    if (axes.child("Rotation")) {
        // A rotation other than the identity would move the points off the grid.
        const char* diag[] = {"Rotation/r11", "Rotation/r22", "Rotation/r33"};
        const char* off[] = {"Rotation/r12", "Rotation/r13", "Rotation/r21", "Rotation/r23", "Rotation/r31", "Rotation/r32"};
        for (const char* d : diag)
            if (number(b, axes, d, 1.0) != 1.0) fail(b.name(), "has a rotated coordinate system; expected none");
        for (const char* o : off)
            if (number(b, axes, o, 0.0) != 0.0) fail(b.name(), "has a rotated coordinate system; expected none");
    }
    const long long nx = integer(b, r3, "MatrixDimension/SizeX");
    const long long ny = integer(b, r3, "MatrixDimension/SizeY");
    const long long nz = r3.first_element_by_path("MatrixDimension/SizeZ") ? integer(b, r3, "MatrixDimension/SizeZ") : 1;
    if (!r3.child("MatrixDimension")) fail(b.name(), "main.xml has no MatrixDimension; point lists are not read");
    if (nz != 1) fail(b.name(), "holds " + std::to_string(nz) + " layers (SizeZ); only single-layer surfaces are read");
    if (r3.child("DataList"))
        fail(b.name(), "keeps its points inline in main.xml (DataList); only binary data (PointDataLink) is read");
    check_grid(b.name(), ny, nx);
    const std::size_t points = std::size_t(nx) * std::size_t(ny);
    const std::string link = trimmed(child_text(r3, "DataLink/PointDataLink"));
    if (link.empty()) fail(b.name(), "main.xml has no DataLink/PointDataLink");
    const std::size_t size = sample_size(type);
    const std::string data = *entry(prefix + link, 0, zip_uint64_t(points * size), true);
    // The declared MD5 of the point data, over the whole entry (read again in full when the
    // entry is longer than the points).
    const std::string md5 = trimmed(child_text(r3, "DataLink/MD5ChecksumPointData"));
    MeasuredSurface s;
    if (!md5.empty()) {
        const zip_int64_t index = zip_name_locate(za.archive, (prefix + link).c_str(), 0);
        zip_stat_t st;
        zip_stat_init(&st);
        zip_stat_index(za.archive, zip_uint64_t(index), 0, &st);
        const std::string whole = st.size == data.size()
                                      ? data
                                      : read_entry(b, za.archive, zip_uint64_t(index),
                                                   std::min<zip_uint64_t>(st.size, zip_uint64_t(k_max_surface_file_bytes)), link);
        const std::string actual = md5_hex(whole);
        if (upper(actual) != upper(md5))
            fail(b.name(), "'" + link + "' has MD5 " + actual + ", main.xml declares " + md5 + "; the data is damaged");
    }
    // md5checksum.hex: "<md5> *main.xml"; a mismatch is kept in the metadata, not refused
    // (editors of main.xml often leave it stale; the data's own checksum is checked above).
    if (const auto sum = entry(prefix + "md5checksum.hex", 4096, std::nullopt, false)) {
        const std::string declared = trimmed(sum->substr(0, std::min<std::size_t>(32, sum->size())));
        s.metadata.push_back({"main_xml_md5", upper(declared) == upper(md5_hex(xml)) ? "ok" : "does not match md5checksum.hex"});
    }
    s.rows = int(ny);
    s.cols = int(nx);
    s.dx_um = dx_m * 1e6;
    s.dy_um = dy_m * 1e6;
    s.format = "x3p";
    s.heights_um.resize(points);
    for (std::size_t i = 0; i < points; ++i)
        s.heights_um[i] = (sample_value(data.data() + i * size, type, false) * z_increment + z_offset) * 1e6;
    // Valid points: one bit per point, least significant bit first; 0 marks a point not measured.
    const std::string valid_link = trimmed(child_text(r3, "DataLink/ValidPointsLink"));
    if (!valid_link.empty()) {
        const std::string valid = *entry(prefix + valid_link, 0, zip_uint64_t((points + 7) / 8), true);
        for (std::size_t i = 0; i < points; ++i)
            if (!((static_cast<unsigned char>(valid[i / 8]) >> (i % 8)) & 1u))
                s.heights_um[i] = std::numeric_limits<double>::quiet_NaN();
        s.metadata.push_back({"valid_points", "read from " + valid_link + " (invalid points are NaN)"});
    }
    if (r3.child("Mask")) s.metadata.push_back({"mask", "main.xml carries a Mask (annotations); not applied"});
    const pugi::xml_node r2 = root.child("Record2");
    const auto meta = [&](const char* key, const char* path) {
        const std::string v = trimmed(child_text(r2, path));
        if (!v.empty()) s.metadata.push_back({key, v});
    };
    meta("date", "Date");
    meta("creator", "Creator");
    std::string instrument;
    for (const char* part : {"Instrument/Manufacturer", "Instrument/Model", "Instrument/Serial", "Instrument/Version"}) {
        const std::string v = trimmed(child_text(r2, part));
        if (!v.empty() && v != "not available" && v != "unknown") instrument += (instrument.empty() ? "" : " ") + v;
    }
    if (!instrument.empty()) s.metadata.push_back({"instrument", instrument});
    meta("calibration_date", "CalibrationDate");
    meta("probing_system", "ProbingSystem/Type");
    meta("probe", "ProbingSystem/Identification");
    meta("comment", "Comment");
    return s;
}

namespace {

struct StringWriter : pugi::xml_writer {
    std::string text;
    void write(const void* data, std::size_t size) override { text.append(static_cast<const char*>(data), size); }
};

std::string iso_date_now() {
    const std::time_t t = std::time(nullptr);
    std::tm tm{};
    gmtime_r(&t, &tm);
    char buffer[32];
    std::strftime(buffer, sizeof buffer, "%Y-%m-%dT%H:%M:%S+00:00", &tm);
    return buffer;
}

std::string exact(double v) {
    std::ostringstream out;
    out.precision(17);
    out << v;
    return out.str();
}

}  // namespace

std::string x3p_bytes(const MeasuredSurface& s) {
    const std::size_t points = s.heights_um.size();
    std::string data(points * 8, '\0');
    std::string valid((points + 7) / 8, '\0');
    bool any_invalid = false;
    for (std::size_t i = 0; i < points; ++i) {
        double z = s.heights_um[i] * 1e-6;  // x3p heights are in metres
        if (std::isnan(s.heights_um[i])) any_invalid = true;
        else valid[i / 8] = char(static_cast<unsigned char>(valid[i / 8]) | (1u << (i % 8)));
        unsigned char bytes[8];
        std::memcpy(bytes, &z, 8);
        const std::uint16_t probe = 1;
        unsigned char first;
        std::memcpy(&first, &probe, 1);
        if (first == 0)
            for (int k = 0; k < 4; ++k) std::swap(bytes[k], bytes[7 - k]);
        std::memcpy(&data[i * 8], bytes, 8);
    }
    // The last byte's unused bits stay 0.

    pugi::xml_document doc;
    pugi::xml_node decl = doc.append_child(pugi::node_declaration);
    decl.append_attribute("version") = "1.0";
    decl.append_attribute("encoding") = "UTF-8";
    decl.append_attribute("standalone") = "no";
    pugi::xml_node root = doc.append_child("p:ISO5436_2");
    root.append_attribute("xmlns:p") = "http://www.opengps.eu/2008/ISO5436_2";
    root.append_attribute("xmlns:xsi") = "http://www.w3.org/2001/XMLSchema-instance";
    root.append_attribute("xsi:schemaLocation") =
        "http://www.opengps.eu/2008/ISO5436_2 http://www.opengps.eu/2008/ISO5436_2/ISO5436_2_XML.xsd";
    const auto add = [](pugi::xml_node parent, const char* name, const std::string& text) {
        pugi::xml_node n = parent.append_child(name);
        n.text().set(text.c_str());
        return n;
    };
    pugi::xml_node r1 = root.append_child("Record1");
    add(r1, "Revision", "ISO5436 - 2000");
    add(r1, "FeatureType", "SUR");
    pugi::xml_node axes = r1.append_child("Axes");
    const auto axis = [&](const char* name, const char* axis_type, const std::optional<double>& increment) {
        pugi::xml_node a = axes.append_child(name);
        add(a, "AxisType", axis_type);
        add(a, "DataType", "D");
        if (increment) add(a, "Increment", exact(*increment));
        add(a, "Offset", "0");
    };
    axis("CX", "I", s.dx_um * 1e-6);
    axis("CY", "I", s.dy_um * 1e-6);
    axis("CZ", "A", 1.0);
    pugi::xml_node r2 = root.append_child("Record2");
    add(r2, "Date", iso_date_now());
    add(r2, "Creator", s.meta("creator").empty() ? "wavebrdf" : s.meta("creator"));
    pugi::xml_node instrument = r2.append_child("Instrument");
    add(instrument, "Manufacturer", "wavebrdf");
    add(instrument, "Model", "wavebrdf");
    add(instrument, "Serial", "not available");
    add(instrument, "Version", k_version);
    add(r2, "CalibrationDate", iso_date_now());
    pugi::xml_node probing = r2.append_child("ProbingSystem");
    add(probing, "Type", "Software");
    add(probing, "Identification", "not available");
    // Every metadata pair, one "key: value" line each: where the surface came from and what
    // conditioning did to it.
    std::string comment;
    for (const auto& [k, v] : s.metadata) comment += (comment.empty() ? "" : "\n") + k + ": " + v;
    add(r2, "Comment", comment);
    pugi::xml_node r3 = root.append_child("Record3");
    pugi::xml_node dim = r3.append_child("MatrixDimension");
    add(dim, "SizeX", std::to_string(s.cols));
    add(dim, "SizeY", std::to_string(s.rows));
    add(dim, "SizeZ", "1");
    pugi::xml_node link = r3.append_child("DataLink");
    add(link, "PointDataLink", "bindata/data.bin");
    add(link, "MD5ChecksumPointData", upper(md5_hex(data)));
    if (any_invalid) {
        add(link, "ValidPointsLink", "bindata/valid.bin");
        add(link, "MD5ChecksumValidPoints", upper(md5_hex(valid)));
    }
    pugi::xml_node r4 = root.append_child("Record4");
    add(r4, "ChecksumFile", "md5checksum.hex");
    StringWriter xml;
    doc.save(xml, "  ", pugi::format_default | pugi::format_no_declaration, pugi::encoding_utf8);
    xml.text = "<?xml version=\"1.0\" encoding=\"UTF-8\" standalone=\"no\" ?>\n" + xml.text;
    const std::string checksum = md5_hex(xml.text) + " *main.xml\n";

    // The archive, built in memory.
    zip_error_t error;
    zip_error_init(&error);
    zip_source_t* source = zip_source_buffer_create(nullptr, 0, 0, &error);
    if (!source) throw std::runtime_error(std::string("cannot make an x3p archive: ") + zip_error_strerror(&error));
    zip_t* za = zip_open_from_source(source, ZIP_TRUNCATE, &error);
    if (!za) {
        zip_source_free(source);
        throw std::runtime_error(std::string("cannot make an x3p archive: ") + zip_error_strerror(&error));
    }
    zip_source_keep(source);
    const auto put = [&](const char* name, const std::string& bytes) {
        zip_source_t* s_entry = zip_source_buffer(za, bytes.data(), bytes.size(), 0);
        if (!s_entry || zip_file_add(za, name, s_entry, ZIP_FL_ENC_UTF_8) < 0) {
            if (s_entry) zip_source_free(s_entry);
            const std::string why = zip_strerror(za);
            zip_discard(za);
            zip_source_free(source);
            throw std::runtime_error(std::string("cannot add ") + name + " to the x3p archive: " + why);
        }
    };
    put("main.xml", xml.text);
    put("md5checksum.hex", checksum);
    zip_dir_add(za, "bindata", ZIP_FL_ENC_UTF_8);
    put("bindata/data.bin", data);
    if (any_invalid) put("bindata/valid.bin", valid);
    if (zip_close(za) != 0) {
        const std::string why = zip_strerror(za);
        zip_discard(za);
        zip_source_free(source);
        throw std::runtime_error("cannot write the x3p archive: " + why);
    }
    zip_stat_t st;
    zip_stat_init(&st);
    std::string out;
    if (zip_source_stat(source, &st) == 0 && zip_source_open(source) == 0) {
        out.resize(static_cast<std::size_t>(st.size));
        const zip_int64_t n = zip_source_read(source, out.data(), st.size);
        zip_source_close(source);
        if (n < 0 || zip_uint64_t(n) != st.size) out.clear();
    }
    zip_source_free(source);
    if (out.empty()) throw std::runtime_error("cannot read back the x3p archive built in memory");
    return out;
}

}  // namespace wavebrdf::surface_io
