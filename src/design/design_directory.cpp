// Writing a design's run directory (design_run.h, docs/design.md).
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <sstream>

#include "design/fabrication_json.h"
#include "wavebrdf/design_run.h"
#include "wavebrdf/fabrication.h"
#include "wavebrdf/heightfield.h"
#include "wavebrdf/io.h"
#include "wavebrdf/run_directory.h"
#include "wavebrdf/text.h"

namespace wavebrdf {

void write_design_directory(const std::string& dir, const DesignResult& result, bool force) {
    prepare_run_directory(RunKind::Design, dir, force);
    const std::filesystem::path d(dir);
    // Heights in µm as a self-describing heightfield: values in texel widths, vscale 1.
    std::vector<double> values(result.heights_um.size());
    for (std::size_t t = 0; t < values.size(); ++t) values[t] = result.heights_um[t] / result.texel_um;
    const Heightfield hf(result.size, result.size, std::move(values), result.texel_um, 1.0);
    write_heightfield_exr((d / "heights.exr").string(), hf, "wavebrdf design");
    // A grayscale relief (--min-feature-um) is written for grayscale lithography: no etch masks.
    const bool grayscale =
        nlohmann::json::parse(result.metrics_json)["constraints"].value("min_feature_um", 0.0) > 0.0;
    // For lithography and printing: heights.png (16-bit, 0 … the top level), the etch masks of
    // the levels (their step is the top level over K − 1) and heights.stl.
    const FabricationFiles files = write_fabrication_exports(
        dir, result.heights_um, result.size, result.size, result.texel_um, result.levels_um.back(),
        grayscale ? 0 : static_cast<int>(result.levels_um.size()));
    auto picture = [&](const std::vector<float>& data) {
        RgbImage image;
        image.rows = image.cols = result.picture_size;
        image.data = data;
        return image;
    };
    write_rgb_exr((d / "target.exr").string(), picture(result.target_picture));
    write_rgb_exr((d / "far_field.exr").string(), picture(result.far_field_picture));
    std::ostringstream csv;
    csv << "iteration,loss,phase,temperature\n";
    for (const DesignStep& s : result.curve)
        csv << s.iteration << ',' << format_shortest(s.loss) << ',' << s.phase << ',' << format_shortest(s.temperature)
            << '\n';
    write_text_atomically((d / "metrics.csv").string(), csv.str());
    // design.json last: its presence says the run directory is complete.
    nlohmann::json j = nlohmann::json::parse(result.metrics_json);
    j["fabrication_files"] = detail::fabrication_files_json(files);
    if (!files.x3p_note.empty()) j["fabrication_files"]["x3p_note"] = files.x3p_note;
    write_text_atomically((d / "design.json").string(), j.dump(2) + "\n");
}

}  // namespace wavebrdf
