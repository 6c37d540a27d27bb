#pragma once
// The output directory of a run (`wavebrdf invert --out`, `wavebrdf recover --out`): which
// files the command writes there, and the rule for reusing a directory. A new run goes into a
// new or empty directory; a non-empty one is refused unless `force`, and then only when it
// holds nothing but the command's own outputs, which are deleted first. Files the command
// does not write are never deleted: their presence refuses the run even with `force`.
#include <string>
#include <vector>

namespace wavebrdf {

enum class RunKind {
    Invert,  // run.json, metrics.csv, checkpoint.json, snapshots/, reference*, truth*, final_*, estimate.*, report.png, curves.png
    Recover,  // run.json, metrics.csv, estimate*, truth*, uncertainty*, reference.npy, final.npy, report.png, observations.json, observations/
    Design,   // design.json, metrics.csv, heights.*, masks*, target.*, far_field.*, report.png
};

// "wavebrdf invert", "wavebrdf recover" or "wavebrdf design".
const char* to_string(RunKind kind);

// Whether `relative` (a path inside the run directory, '/'-separated, e.g. "snapshots/height_0010.npy"
// or "snapshots") is one that the command of `kind` writes, its temporary files
// ("NAME.tmp", "NAME.tmp-…", "NAME.tmp.png", ".NAME.….tmp") included.
bool is_run_output(RunKind kind, const std::string& relative);

// The files and directories under `dir` that the command of `kind` does not write, as paths
// relative to `dir`, sorted (empty when `dir` does not exist).
std::vector<std::string> foreign_files(RunKind kind, const std::string& dir);

// Checks, without changing anything, that a new run of `kind` may write into `dir` (`option`
// names it in messages, e.g. "--out"): it does not exist, or is an empty directory, or `force`
// is set and it holds only the command's own outputs. Throws std::invalid_argument otherwise,
// naming the directory and, for a foreign file, that file.
void check_run_directory(RunKind kind, const std::string& dir, bool force, const std::string& option = "--out");

// check_run_directory, then deletes the command's own outputs in `dir` (files, then its own
// subdirectories once empty) and creates `dir` when missing. Throws std::runtime_error when a
// file cannot be deleted.
void prepare_run_directory(RunKind kind, const std::string& dir, bool force, const std::string& option = "--out");

// The distinct wavelengths (µm) of `per_observation` (each observation's list), in the order
// they first appear: what run.json records as "wavelengths_um".
std::vector<double> distinct_wavelengths_um(const std::vector<std::vector<double>>& per_observation);

}  // namespace wavebrdf
