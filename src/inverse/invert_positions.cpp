// The positions file of `wavebrdf invert --positions FILE.json`, in the library so that the
// fuzzer (fuzz/positions_json_fuzz.cpp) and the tests can reach it.
#include <array>
#include <fstream>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>
#include <vector>

#include "wavebrdf/input_files.h"
#include "wavebrdf/invert.h"

namespace wavebrdf {

std::vector<std::array<double, 2>> read_positions_json(const std::string& path) {
    check_readable_file(path);
    std::ifstream in(path);
    if (!in) throw std::runtime_error(path + ": cannot open the positions file");
    nlohmann::json j;
    try {
        j = nlohmann::json::parse(in);
    } catch (const nlohmann::json::exception& e) {
        throw std::runtime_error(path + ": not valid JSON (" + std::string(e.what()) + ")");
    }
    const nlohmann::json& list = j.is_object() && j.contains("positions") ? j["positions"] : j;
    if (!list.is_array() || list.empty())
        throw std::runtime_error(path + ": expected a non-empty array of [x_um, y_um] pairs");
    std::vector<std::array<double, 2>> out;
    for (const auto& p : list) {
        if (!p.is_array() || p.size() != 2 || !p[0].is_number() || !p[1].is_number())
            throw std::runtime_error(path + ": every position must be [x_um, y_um]");
        out.push_back({p[0].get<double>(), p[1].get<double>()});
    }
    return out;
}

}  // namespace wavebrdf
