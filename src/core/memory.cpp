#include "wavebrdf/memory.h"

#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace wavebrdf {

void throw_out_of_memory(const std::string& what, double bytes) {
    char size[64];
    std::snprintf(size, sizeof size, "%.0f MiB", std::ceil(bytes / double(1 << 20)));
    throw OutOfMemory("out of memory allocating " + what + " (" + size + ")");
}

std::uint64_t physical_memory_bytes() {
    const long pages = ::sysconf(_SC_PHYS_PAGES), page = ::sysconf(_SC_PAGESIZE);
    if (pages <= 0 || page <= 0) return 0;
    return std::uint64_t(pages) * std::uint64_t(page);
}

MemoryLimit memory_limit(double max_memory_gb) {
    if (!std::isfinite(max_memory_gb) || max_memory_gb < 0.0) {
        char got[64];
        std::snprintf(got, sizeof got, "%g", max_memory_gb);
        throw std::invalid_argument(std::string("max-memory-gb ") + got +
                                    " is invalid; expected a finite value > 0 (GB), or 0 for the physical memory");
    }
    if (max_memory_gb > 0.0) return {max_memory_gb * 1e9, "max-memory-gb"};
    const std::uint64_t physical = physical_memory_bytes();
    return {physical > 0 ? double(physical) : HUGE_VAL, "physical memory"};
}

std::string format_bytes(double bytes) {
    const char* units[] = {"bytes", "kB", "MB", "GB", "TB", "PB"};
    int u = 0;
    while (u < 5 && bytes >= 1000.0) {
        bytes /= 1000.0;
        ++u;
    }
    char buf[64];
    std::snprintf(buf, sizeof buf, u == 0 ? "%.0f %s" : "%.3g %s", bytes, units[u]);
    return buf;
}

void require_memory(double needed_bytes, const MemoryLimit& limit, const std::string& what, const std::string& hint) {
    if (!(needed_bytes > limit.bytes)) return;
    throw OutOfMemory(what + " needs about " + format_bytes(needed_bytes) + "; the limit is " +
                      format_bytes(limit.bytes) + " (" + limit.source + "); raise it with " + hint);
}

}  // namespace wavebrdf
