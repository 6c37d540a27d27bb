// Loading the optional plugins (src/core/plugin.h).
#include "core/plugin.h"

#include <dlfcn.h>
#include <link.h>

#include <cstdlib>
#include <cstring>
#include <map>
#include <mutex>
#include <stdexcept>
#include <vector>

namespace wavebrdf::detail {

namespace {

std::string folder_of(const std::string& file) {
    const std::size_t slash = file.rfind('/');
    return slash == std::string::npos ? std::string(".") : file.substr(0, slash);
}

// The folders to look in, in order (src/core/plugin.h).
std::vector<std::string> plugin_folders() {
    std::vector<std::string> folders;
    if (const char* dir = std::getenv("WAVEBRDF_PLUGIN_DIR"); dir != nullptr && *dir != '\0') folders.push_back(dir);
#ifdef WAVEBRDF_PLUGIN_BUILD_DIR
    folders.push_back(WAVEBRDF_PLUGIN_BUILD_DIR);
#endif
    Dl_info info{};
    if (dladdr(reinterpret_cast<void*>(&plugin_folders), &info) != 0 && info.dli_fname != nullptr &&
        info.dli_fname[0] != '\0') {
        const std::string here = folder_of(info.dli_fname);
        folders.push_back(here);
        folders.push_back(here + "/../lib/wavebrdf");
    }
#ifdef WAVEBRDF_PLUGIN_INSTALL_DIR
    folders.push_back(WAVEBRDF_PLUGIN_INSTALL_DIR);
#endif
    return folders;
}

void* load(const std::string& name) {
    const std::string file = "libwavebrdf_" + name + ".so";
    std::string reasons;
    for (const std::string& folder : plugin_folders()) {
        const std::string path = folder + "/" + file;
        // RTLD_LOCAL: the plugin's libraries stay its own; RTLD_NOW: a missing library fails here.
        if (void* handle = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL)) return handle;
        const char* why = dlerror();
        // A missing file is the expected case for all folders but one; other reasons are said.
        if (why != nullptr && std::strstr(why, "No such file") == nullptr) reasons += std::string("; ") + why;
    }
    throw std::runtime_error("wavebrdf: the " + name + " plugin " + file +
                             " cannot be loaded (looked beside the program, in its ../lib/wavebrdf, the build "
                             "and install trees and $WAVEBRDF_PLUGIN_DIR" +
                             (reasons.empty() ? std::string(": not found)") : ")" + reasons));
}

}  // namespace

void* plugin_symbol(const char* name, const char* symbol) {
    static std::mutex mutex;
    static std::map<std::string, void*> handles;
    std::lock_guard<std::mutex> lock(mutex);
    void*& handle = handles[name];
    if (handle == nullptr) handle = load(name);
    dlerror();
    void* address = dlsym(handle, symbol);
    if (address == nullptr)
        throw std::runtime_error(std::string("wavebrdf: the ") + name + " plugin has no symbol " + symbol +
                                 " (a plugin of another version?)");
    return address;
}

bool library_loaded(const char* fragment) {
    struct Search {
        const char* fragment;
        bool found;
    } search{fragment, false};
    dl_iterate_phdr(
        [](dl_phdr_info* info, std::size_t, void* data) {
            auto* s = static_cast<Search*>(data);
            if (info->dlpi_name != nullptr && std::strstr(info->dlpi_name, s->fragment) != nullptr) s->found = true;
            return s->found ? 1 : 0;
        },
        &search);
    return search.found;
}

}  // namespace wavebrdf::detail
