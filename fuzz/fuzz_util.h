#pragma once
// Shared by the libFuzzer targets: the readers under test take a path, so each input is
// written to a file in a private temporary directory (removed at exit), and every exception
// the readers are documented to throw counts as a clean rejection.
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <fstream>
#include <new>
#include <stdexcept>
#include <string>
#include <typeinfo>

namespace wavebrdf::fuzz {

// A directory of this process's own under $TMPDIR (or /tmp), created on first use and removed
// at exit. Never destroyed (a plain pointer): the exit handler that removes it needs its name.
inline const std::string& scratch_dir() {
    static const std::string* const dir = [] {
        const char* tmp = std::getenv("TMPDIR");
        const std::string base = (tmp != nullptr && *tmp != '\0') ? tmp : "/tmp";
        auto* d = new std::string(base + "/wavebrdf-fuzz-" + std::to_string(static_cast<long long>(::getpid())));
        std::filesystem::create_directories(*d);
        std::atexit([] {
            std::error_code ignored;
            std::filesystem::remove_all(scratch_dir(), ignored);
        });
        return d;
    }();
    return *dir;
}

// Writes `size` bytes to scratch_dir()/name (replacing it) and returns the file's path.
inline std::string write_input(const std::string& name, const std::uint8_t* data, std::size_t size) {
    const std::string path = scratch_dir() + "/" + name;
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
    out.close();
    if (!out) {
        std::fprintf(stderr, "fuzz: cannot write %s\n", path.c_str());
        std::abort();
    }
    return path;
}

// Runs `read`; the exceptions our readers promise (std::runtime_error, std::invalid_argument,
// std::domain_error, each with a message) are a clean rejection. Anything else escaping —
// std::bad_alloc, std::out_of_range, a library's own exception type — breaks the documented
// contract, so it aborts and libFuzzer records the input as a crash.
template <typename Read>
void expect_clean(Read&& read) {
    try {
        read();
    } catch (const std::runtime_error& e) {
        if (e.what()[0] == '\0') std::abort();
    } catch (const std::invalid_argument& e) {
        if (e.what()[0] == '\0') std::abort();
    } catch (const std::domain_error& e) {
        if (e.what()[0] == '\0') std::abort();
    } catch (const std::exception& e) {
        std::fprintf(stderr, "fuzz: undocumented exception %s: %s\n", typeid(e).name(), e.what());
        std::abort();
    }
}

}  // namespace wavebrdf::fuzz
