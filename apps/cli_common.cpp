#include "cli_common.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <system_error>
#include <stdexcept>

namespace wavebrdf::cli {

void parse_size(const std::string& option, const std::string& text, int& rows, int& cols) {
    const auto x = text.find_first_of("xX");
    try {
        std::size_t used = 0;
        rows = std::stoi(text.substr(0, x), &used);
        if (used != (x == std::string::npos ? text.size() : x)) throw std::invalid_argument(text);
        cols = rows;
        if (x != std::string::npos) {
            cols = std::stoi(text.substr(x + 1), &used);
            if (used != text.size() - x - 1) throw std::invalid_argument(text);
        }
    } catch (const std::logic_error&) {
        throw std::invalid_argument(option + " '" + text + "' is invalid; expected N or NxM (e.g. 512 or 256x384)");
    }
    if (rows < 1 || cols < 1 || rows > 16384 || cols > 16384)
        throw std::invalid_argument(option + " '" + text + "' is out of range; expected 1 to 16384 per side");
}

void check_distinct_files(const std::vector<std::pair<std::string, std::string>>& files) {
    namespace fs = std::filesystem;
    std::vector<fs::path> canonical(files.size());
    for (std::size_t k = 0; k < files.size(); ++k) {
        if (files[k].second.empty()) continue;
        // Absolute first: weakly_canonical leaves a relative path whose first part does not
        // exist relative, so `o.exr` and `./o.exr` would differ.
        std::error_code ec;
        canonical[k] = fs::weakly_canonical(fs::absolute(files[k].second, ec), ec);
        if (ec) canonical[k] = fs::path(files[k].second).lexically_normal();
        for (std::size_t i = 0; i < k; ++i)
            if (!files[i].second.empty() && canonical[i] == canonical[k])
                throw std::invalid_argument(files[i].first + " " + files[i].second + " and " + files[k].first + " " +
                                            files[k].second + " name the same file; expected different paths");
    }
}

double auto_exposure(const std::vector<double>& slice) {
    std::vector<double> v(slice.begin(), slice.end());
    if (v.empty()) return 0.0;
    const std::size_t k = std::min(v.size() - 1, static_cast<std::size_t>(0.999 * double(v.size())));
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
    return v[k] > 0 ? -std::log2(v[k]) + 2.0 : 0.0;
}

}  // namespace wavebrdf::cli
