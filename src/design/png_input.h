#pragma once
// Internal: the start of reading a PNG picture (a pattern target's image, a plate's picture)
// through libpng's simplified API, with the checks every file reader makes first.
#include <png.h>

#include <string>

namespace wavebrdf::detail {

// Begins reading the PNG at `path` into `image` (its header read, nothing allocated yet): a
// regular file only (a FIFO or device would block or never end), and a declared size that the
// file's compressed data can hold. A pixel takes at least one bit of the image data, and zlib
// expands at most 1032 times, so a file of S bytes holds at most rows × (1 + ⌈cols / 8⌉) ≤ 1032 S
// bytes of it: a small file declaring a huge picture is refused before its pixels are allocated.
// `what` leads every message ("picture 'x.png'"); std::invalid_argument.
void begin_png_read(png_image& image, const std::string& path, const std::string& what);

}  // namespace wavebrdf::detail
