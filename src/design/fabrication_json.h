#pragma once
// Internal: design.json's `fabrication_files` block (file names relative to the run directory)
// for a single design's directory and a plate's.
#include <filesystem>
#include <nlohmann/json.hpp>

#include "wavebrdf/fabrication.h"

namespace wavebrdf::detail {

inline nlohmann::json fabrication_files_json(const FabricationFiles& files) {
    nlohmann::json masks = nlohmann::json::array();
    for (const LevelMask& m : files.masks)
        masks.push_back({{"file", std::filesystem::path(m.path).filename().string()}, {"depth_um", m.depth_um},
                         {"weight", m.weight}});
    return {{"heights_png", "heights.png"},
            {"heights_stl", files.heights_stl.empty() ? "" : "heights.stl"},
            {"stl_note", files.note},
            {"masks_json", files.masks_json.empty() ? "" : "masks.json"},
            {"masks", masks},
            {"heights_x3p", files.heights_x3p.empty() ? "" : "heights.x3p"}};
}

}  // namespace wavebrdf::detail
