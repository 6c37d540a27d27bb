#pragma once
// Input files that are files: what every reader checks before it opens a path.
#include <string>

namespace wavebrdf {

// Throws std::runtime_error "<path>: is a FIFO, not a regular file; expected a regular file to
// read" when `path` exists and is not a regular file after following symbolic links (a FIFO,
// device, socket or directory): a read of a FIFO blocks forever and one of /dev/zero never
// ends. Absent paths pass (the reader names them). Every file reader calls it before opening.
void check_readable_file(const std::string& path);

}  // namespace wavebrdf
