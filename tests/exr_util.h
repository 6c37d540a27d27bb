#pragma once
// OpenEXR helpers for tests that write hostile files.
#include <ImfHeader.h>

#include <string>

namespace wavebrdf::test {

// A copy of `header` without the attribute `name`. Header::erase of OpenEXR 3.1 drops the
// attribute from its map without deleting it (a leak LeakSanitizer reports), so the copy is
// built attribute by attribute instead: a default header, every other attribute inserted
// (an attribute a default header already has keeps its type and takes the value).
inline Imf::Header header_without(const Imf::Header& header, const std::string& name) {
    Imf::Header copy;
    for (Imf::Header::ConstIterator it = header.begin(); it != header.end(); ++it)
        if (name != it.name()) copy.insert(it.name(), it.attribute());
    return copy;
}

}  // namespace wavebrdf::test
