#include "wavebrdf/run_directory.h"

#include <algorithm>
#include <filesystem>
#include <regex>
#include <stdexcept>
#include <system_error>

namespace wavebrdf {

namespace fs = std::filesystem;

namespace {

// The name without a temporary suffix of an atomic write: "NAME.tmp", "NAME.tmp-PID…",
// "NAME.tmp.png", or Python's mkstemp ".NAME.XXXX.tmp".
std::string without_temporary_suffix(const std::string& relative) {
    static const std::regex plain(R"(^(.*)\.tmp(?:[-.][A-Za-z0-9_.-]*)?$)");
    static const std::regex hidden(R"(^(.*/)?\.([^/]+)\.[A-Za-z0-9_]+\.tmp$)");
    std::smatch m;
    if (std::regex_match(relative, m, hidden)) return m[1].str() + m[2].str();
    if (std::regex_match(relative, m, plain)) return m[1].str();
    return relative;
}

}  // namespace

const char* to_string(RunKind kind) {
    switch (kind) {
        case RunKind::Invert: return "wavebrdf invert";
        case RunKind::Recover: return "wavebrdf recover";
        case RunKind::Design: return "wavebrdf design";
    }
    return "wavebrdf";
}

bool is_run_output(RunKind kind, const std::string& relative) {
    static const std::regex invert_names(
        R"(^(run\.json|metrics\.csv|checkpoint\.json|reference\.npy|truth_height\.npy|truth\.exr|estimate\.exr|)"
        R"(estimate\.png|report\.png|curves\.png|(reference|final)_[0-9]{3,}\.(exr|png)|snapshots|)"
        R"(snapshots/(height|slice|gradient)_[0-9]{4,}\.npy)$)");
    static const std::regex recover_names(
        R"(^(run\.json|metrics\.csv|estimate\.exr|estimate\.png|estimate_height\.npy|truth\.exr|truth_height\.npy|)"
        R"(uncertainty\.exr|uncertainty\.json|uncertainty_height\.npy|calibration\.json|psd\.csv|)"
        R"(reference\.npy|final\.npy|report\.png|observations\.json|observations\.(h5|hdf5|cxi)|observations|observations/slice_[0-9]{4,}\.exr)$)");
    static const std::regex design_names(
        R"(^(design\.json|metrics\.csv|heights\.(exr|png|stl|x3p)|masks\.json|masks_[0-9]{2,}\.png|)"
        R"((target|far_field|plate)\.(exr|png)|report\.png)$)");
    const std::string name = without_temporary_suffix(relative);
    if (kind == RunKind::Design) return std::regex_match(name, design_names);
    return std::regex_match(name, kind == RunKind::Invert ? invert_names : recover_names);
}

std::vector<std::string> foreign_files(RunKind kind, const std::string& dir) {
    std::vector<std::string> out;
    std::error_code ec;
    if (!fs::is_directory(dir, ec)) return out;
    for (auto it = fs::recursive_directory_iterator(dir, ec); !ec && it != fs::recursive_directory_iterator();
         it.increment(ec)) {
        const std::string relative = it->path().lexically_relative(dir).generic_string();
        // Only the command's own subdirectories are entered (as real directories, not links).
        if (!is_run_output(kind, relative) || (it->is_directory() && it->is_symlink())) {
            out.push_back(relative);
            if (it->is_directory()) it.disable_recursion_pending();
        } else if (!it->is_directory() && !it->is_regular_file() && !it->is_symlink()) {
            out.push_back(relative);  // a FIFO or device under an own name is not ours either
        }
    }
    if (ec) throw std::runtime_error(dir + ": cannot list the directory (" + ec.message() + ")");
    std::sort(out.begin(), out.end());
    return out;
}

void check_run_directory(RunKind kind, const std::string& dir, bool force, const std::string& option) {
    std::error_code ec;
    const fs::file_status status = fs::symlink_status(dir, ec);
    if (!fs::exists(status)) return;
    if (!fs::is_directory(fs::status(dir, ec)))
        throw std::invalid_argument(option + " " + dir +
                                    " exists and is not a directory; expected a directory for the run");
    if (fs::is_empty(dir, ec)) return;
    const std::vector<std::string> foreign = foreign_files(kind, dir);
    if (!foreign.empty())
        throw std::invalid_argument(
            option + " " + dir + " is not empty and holds '" + foreign.front() + "'" +
            (foreign.size() > 1 ? " and " + std::to_string(foreign.size() - 1) + " more" : std::string()) + ", which " +
            to_string(kind) +
            " does not write; expected a new or empty directory (--force replaces only a directory of " +
            to_string(kind) + "'s own outputs)");
    if (!force)
        throw std::invalid_argument(
            option + " " + dir + " holds the outputs of another run; expected a new or empty directory, " +
            (kind == RunKind::Invert ? std::string("--resume DIR to continue that run, ") : std::string()) +
            "or --force to replace that run");
}

void prepare_run_directory(RunKind kind, const std::string& dir, bool force, const std::string& option) {
    check_run_directory(kind, dir, force, option);
    std::error_code ec;
    if (fs::is_directory(dir, ec)) {
        std::vector<fs::path> files, dirs;
        for (auto it = fs::recursive_directory_iterator(dir, ec); !ec && it != fs::recursive_directory_iterator();
             it.increment(ec))
            (it->is_directory() && !it->is_symlink() ? dirs : files).push_back(it->path());
        for (const fs::path& f : files)
            if (!fs::remove(f, ec) && ec)
                throw std::runtime_error(f.string() + ": cannot delete the old run's file (" + ec.message() + ")");
        for (auto d = dirs.rbegin(); d != dirs.rend(); ++d) fs::remove(*d, ec);
    }
    fs::create_directories(dir);
}

std::vector<double> distinct_wavelengths_um(const std::vector<std::vector<double>>& per_observation) {
    std::vector<double> out;
    for (const auto& lambdas : per_observation)
        for (double l : lambdas)
            if (std::find(out.begin(), out.end(), l) == out.end()) out.push_back(l);
    return out;
}

}  // namespace wavebrdf
