// `wavebrdf convert`: a surface file to another format (by OUT's extension), conditioned on the
// way (conditioning.h); every step is printed and kept in the file's metadata.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>

#include "cli_common.h"
#include "commands.h"
#include "surface_options.h"
#include "unit_check.h"
#include "wavebrdf/io.h"

namespace wavebrdf::cli {

namespace {

struct ConvertArgs {
    std::string in, out;
    double spacing_um = 0.0;
    CLI::Option* spacing_option = nullptr;
    double lambda_um = 0.5;
    bool quiet = false;
    ConditioningArgs conditioning;
};

void run(const ConvertArgs& a) {
    validate_lambda(a.lambda_um);
    check_distinct_files({{"IN", a.in}, {"OUT", a.out}});
    check_output_format("OUT", a.out, {".x3p", ".sdf", ".npy", ".exr"});          // before the input is read
    const ConditioningOptions options = to_conditioning_options(a.conditioning);  // bad options before reading
    (void)options;
    check_writable(a.out);
    const std::optional<double> spacing =
        a.spacing_option->count() > 0 ? std::optional<double>(a.spacing_um) : std::nullopt;
    const MeasuredSurface input = read_surface(a.in, spacing);
    const MeasuredSurface surface = condition_and_report(input, a.conditioning, a.quiet);
    // A heightfield EXR holds every point: say which option fills them, before the writer refuses.
    std::string ext = std::filesystem::path(a.out).extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    if (ext == ".exr" && surface.invalid_count() > 0)
        throw std::invalid_argument(a.in + " has " + std::to_string(surface.invalid_count()) +
                                    " unmeasured points (NaN) and a heightfield EXR holds every point; expected "
                                    "--fill nearest, harmonic or mean");
    write_surface(a.out, surface);
    if (!a.quiet)
        std::fprintf(stderr, "%s: %dx%d points, spacing %.6g x %.6g um (x, y), %zu unmeasured\n", a.out.c_str(),
                     surface.rows, surface.cols, surface.dx_um, surface.dy_um, surface.invalid_count());
    // The unit check where the result is a heightfield the model can take (square, complete).
    if (surface.invalid_count() == 0 && std::abs(surface.dx_um - surface.dy_um) <= 1e-6 * surface.dx_um)
        print_units(warn_units(to_heightfield(surface, a.out), a.lambda_um, a.out), a.out, a.quiet);
}

}  // namespace

void add_convert_command(CLI::App& app) {
    auto a = std::make_shared<ConvertArgs>();
    CLI::App* cmd = app.add_subcommand("convert", "Convert and condition a measured surface file (docs/surfaces.md)");
    cmd->add_option("IN", a->in, "surface file (read by its content)")->required();
    cmd->add_option("OUT", a->out, "output; format from the extension: .x3p, .sdf, .npy or .exr")->required();
    a->spacing_option = cmd->add_option("--spacing-um", a->spacing_um, "spacing in um for IN without one (npy, text)");
    cmd->add_option("--lambda-um", a->lambda_um, "wavelength for the phase rms of the unit check")
        ->capture_default_str();
    cmd->add_flag("--quiet", a->quiet, "print nothing but warnings and errors");
    add_conditioning_options(cmd, a->conditioning);
    cmd->callback([a] { run(*a); });
}

}  // namespace wavebrdf::cli
