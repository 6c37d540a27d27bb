#include "cli_common.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>
#include <sstream>
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

namespace {

std::size_t edit_distance(const std::string& a, const std::string& b) {
    std::vector<std::size_t> row(b.size() + 1);
    for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
    for (std::size_t i = 1; i <= a.size(); ++i) {
        std::size_t diagonal = row[0];
        row[0] = i;
        for (std::size_t j = 1; j <= b.size(); ++j) {
            const std::size_t up = row[j];
            row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] == b[j - 1] ? 0 : 1)});
            diagonal = up;
        }
    }
    return row[b.size()];
}

// The candidate nearest to `word`: the only one it begins, else the closest within a third of
// its letters (ties: none).
std::string nearest(const std::string& word, const std::vector<std::string>& candidates) {
    std::vector<std::string> prefixed;
    for (const std::string& c : candidates)
        if (c.size() > word.size() && c.compare(0, word.size(), word) == 0) prefixed.push_back(c);
    if (prefixed.size() == 1) return prefixed.front();
    std::string best;
    std::size_t best_distance = std::max<std::size_t>(2, word.size() / 3) + 1;
    bool tie = false;
    for (const std::string& c : candidates) {
        const std::size_t d = edit_distance(word, c);
        if (d < best_distance) {
            best = c;
            best_distance = d;
            tie = false;
        } else if (d == best_distance) {
            tie = true;
        }
    }
    return tie ? std::string() : best;
}

}  // namespace

std::string did_you_mean(const CLI::App& app, const std::string& message, const std::vector<std::string>& args) {
    std::vector<const CLI::App*> parsed;
    for (const CLI::App* sub : app.get_subcommands()) parsed.push_back(sub);
    if (parsed.empty()) {
        std::vector<std::string> commands;
        for (const CLI::App* sub : app.get_subcommands([](const CLI::App*) { return true; }))
            commands.push_back(sub->get_name());
        for (const std::string& word : args) {
            if (word.empty() || word[0] == '-') continue;
            const std::string found = nearest(word, commands);
            return !found.empty() && found != word ? "; '" + word + "' is not a command; did you mean " + found + "?"
                                                   : std::string();
        }
    }
    const std::size_t colon = message.find(": ");
    if (colon == std::string::npos) return "";
    std::istringstream words(message.substr(colon + 2));
    std::string word;
    while (words >> word) {
        word = word.substr(0, word.find('='));
        std::vector<std::string> candidates;
        if (word.rfind("--", 0) == 0) {
            const CLI::App& in = parsed.empty() ? app : *parsed.front();
            for (const CLI::Option* option : in.get_options())
                for (const std::string& name : option->get_lnames()) candidates.push_back("--" + name);
        } else if (parsed.empty() && !word.empty() && word[0] != '-') {
            for (const CLI::App* sub : app.get_subcommands([](const CLI::App*) { return true; }))
                candidates.push_back(sub->get_name());
        } else {
            continue;
        }
        const std::string found = nearest(word, candidates);
        if (!found.empty() && found != word) return "; did you mean " + found + "?";
    }
    return "";
}

std::string seed_error(const std::string& text) {
    const std::string max = "18446744073709551615";
    const std::size_t first = text.find_first_not_of('0');
    const std::string digits = first == std::string::npos ? "0" : text.substr(first);
    const bool all_digits = !text.empty() && text.find_first_not_of("0123456789") == std::string::npos;
    if (!all_digits || digits.size() > max.size() || (digits.size() == max.size() && digits > max))
        return "seed " + text + " is invalid; expected an integer from 0 to 18446744073709551615";
    return "";
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

std::pair<CLI::Option*, CLI::Option*> add_grid_options(CLI::App* cmd, std::string& size, double& texel_um,
                                                       double& vscale) {
    cmd->add_option("--size", size, "heightfield size NxM for the generated truth or with --observations")
        ->capture_default_str();
    CLI::Option* texel =
        cmd->add_option("--texel-um", texel_um, "texel width w in um (with --truth: the file's if it says)")
            ->capture_default_str();
    CLI::Option* scale =
        cmd->add_option("--vscale", vscale, "vertical scale v (with --truth: the file's if it says)")->capture_default_str();
    return {texel, scale};
}

void add_light_options(CLI::App* cmd, double& light_x, double& light_y) {
    cmd->add_option("--light-x", light_x, "projected light direction x")->capture_default_str();
    cmd->add_option("--light-y", light_y, "projected light direction y")->capture_default_str();
}

void add_memory_option(CLI::App* cmd, double& max_memory_gb) {
    cmd->add_option("--max-memory-gb", max_memory_gb,
                    "refuse a run whose estimated peak memory exceeds this many GB (0: the physical memory)")
        ->capture_default_str();
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
