// An OpenEXR file opened for reading after the checks that must come before OpenEXR allocates
// anything (src/io/io.cpp): for the library's EXR readers (heightfields, slices, tables).
#pragma once

#include <memory>
#include <string>
#include <vector>

#include <ImfHeader.h>
#include <ImfInputFile.h>

namespace wavebrdf::detail {

// Opens `path` (std::runtime_error naming it otherwise) after refusing, from the raw bytes and
// then the header, what would make OpenEXR or the reader allocate more than the file can be:
// a missing, non-regular or non-EXR file, header attributes larger than the file, more than
// k_max_exr_channels channels, tiles or sides beyond the limits (io.h), several parts, more than
// k_max_exr_pixels pixels, and pixel data larger than the file's size times the largest
// expansion of its compression (exr_expansion_limit). No pixel is read.
struct ExrSource {
    explicit ExrSource(const std::string& path);

    const Imf::Header& header() const { return m_file->header(); }
    bool has_channel(const char* name) const;

    // Reads channels[c] into data[k * stride + c] (float, whatever the stored type), row-major
    // from the data window's top-left corner, which Slice::Make maps to element 0.
    void read(const std::vector<std::string>& channels, std::vector<float>& data) const;

    // Reads rows first_row … last_row (0-based from the data window's top, inclusive) of one
    // channel as float into out[(r - first_row) * m_cols + j]; `out` holds that many values.
    void read_rows(const char* channel, int first_row, int last_row, float* out) const;
    // The same for several channels, interleaved: out[((r - first_row) * m_cols + j) * n + c]
    // for channels[c], n = channels.size().
    void read_rows(const std::vector<std::string>& channels, int first_row, int last_row, float* out) const;

    std::string m_path;
    std::unique_ptr<Imf::InputFile> m_file;
    int m_rows = 0;
    int m_cols = 0;
};

// The largest factor by which `compression` (an Imf::Compression value) can expand the bytes it
// stores: uncompressed 1, RLE 64 (a run of 127 bytes in 2), ZIP and ZIPS 1032 (deflate's
// limit), PXR24 1376 (deflate of floats cut to 24 bits), B44 and B44A 11 (a flat 4 × 4 block of
// halves in 3 bytes); 0 for the others (PIZ, DWAA, DWAB and later codecs): no bound from the
// file's size.
double exr_expansion_limit(int compression);

}  // namespace wavebrdf::detail
