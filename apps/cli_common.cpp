#include "cli_common.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>
#include <system_error>
#include <stdexcept>

#include "commands.h"
#include "wavebrdf/render_options.h"
#include "wavebrdf/threads.h"

namespace wavebrdf::cli {

int parse_threads(const std::string& text) {
    const auto bad = [&] {
        return std::invalid_argument("--threads " + text + " is invalid; expected an integer from 1 to " +
                                     std::to_string(k_max_thread_count));
    };
    const std::size_t first = text.find_first_not_of(" \t"), last = text.find_last_not_of(" \t");
    if (first == std::string::npos || last - first + 1 > 4) throw bad();
    int value = 0;
    for (std::size_t k = first; k <= last; ++k) {
        if (text[k] < '0' || text[k] > '9') throw bad();
        value = value * 10 + (text[k] - '0');
    }
    if (value < 1 || value > k_max_thread_count) throw bad();
    return value;
}

void add_threads_option(CLI::App* cmd) {
    // Applied while the option is processed, which CLI11 does before the command's callback runs.
    cmd->add_option("--threads")
        ->description("threads for this command, 1 to 1024 (default: OMP_NUM_THREADS, else all cores)")
        ->type_name("N")
        ->each([](const std::string& text) { set_thread_count(parse_threads(text)); });
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

HeightfieldScale resolve_scale_with_warnings(const std::string& path, std::optional<double> texel_um,
                                             std::optional<double> vscale, const std::string& texel_option,
                                             const std::string& vscale_option, double default_texel_um,
                                             double default_vscale) {
    HeightfieldScale scale = resolve_heightfield_scale(path, read_heightfield_attributes(path), texel_um, vscale,
                                                       texel_option, vscale_option, default_texel_um, default_vscale);
    for (const std::string& w : scale.warnings) std::fprintf(stderr, "wavebrdf: warning: %s\n", w.c_str());
    return scale;
}

void add_render_path_options(CLI::App* cmd, RenderPathArgs& args) {
    cmd->add_option("--path", args.path,
                    "rendering path: auto (chosen by cost), separable (matrix products), fft (the FFT engine) or "
                    "direct (every pixel sums every kernel)")
        ->capture_default_str();
    cmd->add_option("--tolerance", args.tolerance,
                    "separable (GHS, RGHS, Kirchhoff) and fft paths: error bound relative to the slice peak, "
                    "1e-12 to 1e-2")
        ->capture_default_str();
}

void apply_render_path_options(const RenderPathArgs& args, RenderOptions& options) {
    options.path = parse_render_path(args.path, "--path");
    validate_render_tolerance(args.tolerance, "--tolerance");
    options.tolerance = args.tolerance;
}

void run_on_world(const std::function<void(const Communicator& world)>& command) {
    const std::shared_ptr<const Communicator> world = world_communicator();
    if (world->size() == 1) {
        command(*world);
        return;
    }
    std::optional<ExitStatus> status;  // not a failure: each rank ends with its own
    try {
        run_agreed(*world, [&] {
            try {
                command(*world);
            } catch (const ExitStatus& s) {
                status = s;
            }
        });
    } catch (const RankFailed& e) {
        if (world->is_root()) std::fprintf(stderr, "wavebrdf: error: %s\n", e.what());
        throw ExitStatus{1};
    }
    if (status) throw *status;
}

}  // namespace wavebrdf::cli
