// Writing a design's run directory (design_run.h, docs/design.md).
#include <cstdio>
#include <filesystem>
#include <sstream>

#include "wavebrdf/design_run.h"
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
    write_text_atomically((d / "design.json").string(), result.metrics_json + "\n");
}

}  // namespace wavebrdf
