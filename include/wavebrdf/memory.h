#pragma once
// Memory: how much the machine has, refusing work whose estimate does not fit a limit, and
// out-of-memory errors that say what was being allocated.
#include <cstdint>
#include <memory>
#include <new>
#include <string>

namespace wavebrdf {

// A std::bad_alloc that says what was being allocated and how much ("out of memory allocating
// the 1024x1024 slice's factor matrices (64 MiB)"), or that an estimate exceeds the limit.
// Python sees MemoryError with this message; the CLI prints it.
class OutOfMemory : public std::bad_alloc {
public:
    explicit OutOfMemory(const std::string& message) : m_message(std::make_shared<const std::string>(message)) {}
    const char* what() const noexcept override { return m_message->c_str(); }

private:
    std::shared_ptr<const std::string> m_message;  // shared: copying never throws
};

// Throws OutOfMemory("out of memory allocating WHAT (N MiB)"); `bytes` ≥ 0.
[[noreturn]] void throw_out_of_memory(const std::string& what, double bytes);

// Runs `allocate()` and returns its result; a std::bad_alloc from it becomes OutOfMemory
// naming `what` and `bytes` (an OutOfMemory passes unchanged).
template <typename Allocate>
auto allocating(const std::string& what, double bytes, Allocate&& allocate) -> decltype(allocate()) {
    try {
        return allocate();
    } catch (const OutOfMemory&) {
        throw;
    } catch (const std::bad_alloc&) {
        throw_out_of_memory(what, bytes);
    }
}

// The machine's physical memory in bytes (sysconf), or 0 when it cannot be read.
std::uint64_t physical_memory_bytes();

// A memory limit: `bytes` and where it came from (for messages).
struct MemoryLimit {
    double bytes = 0.0;
    std::string source;  // "physical memory" or "max-memory-gb"
};

// The limit for a `max_memory_gb` option: that many GB (1e9 bytes) when > 0, the physical
// memory when 0 (unlimited when that is unknown). std::invalid_argument for a negative or
// non-finite value.
MemoryLimit memory_limit(double max_memory_gb);

// Throws OutOfMemory("WHAT needs about X GB; the limit is Y GB (SOURCE); raise it with HINT")
// when `needed_bytes` exceeds the limit. `hint`: how the user raises it ("--max-memory-gb",
// "max_memory_gb=").
void require_memory(double needed_bytes, const MemoryLimit& limit, const std::string& what,
                    const std::string& hint = "--max-memory-gb");

// "1.5 GB" / "250 MB" / "12 kB": bytes in decimal units, 3 significant digits.
std::string format_bytes(double bytes);

}  // namespace wavebrdf
