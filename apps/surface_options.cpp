#include "surface_options.h"

#include <cstdio>


namespace wavebrdf::cli {

void add_conditioning_options(CLI::App* cmd, ConditioningArgs& a) {
    const std::string group = "Conditioning (in this order; docs/surfaces.md)";
    a.resample_option = cmd->add_option("--resample-um", a.resample_um,
                                        "resample to square texels of W um (bilinear), over the same extent")
                            ->group(group)
                            ->type_name("W");
    cmd->add_option("--fill", a.fill,
                    "unmeasured points: none (refuse them), nearest, harmonic (Laplace inpainting) or mean")
        ->group(group)
        ->capture_default_str();
    cmd->add_option("--detrend", a.detrend,
                    "form removed by least squares over the measured points: none, mean, plane or poly:N (N <= 10)")
        ->group(group)
        ->capture_default_str();
    cmd->add_option("--crop", a.crop, "keep ROWS x COLS points from row R0, column C0 (done first)")
        ->group(group)
        ->type_name("R0,C0,ROWS,COLS");
    cmd->add_option("--periodic", a.periodic,
                    "make the tile periodic: none, smooth (periodic-plus-smooth, Moisan 2011) or mirror "
                    "(mirror tiling, twice the size each way)")
        ->group(group)
        ->capture_default_str();
}

ConditioningOptions to_conditioning_options(const ConditioningArgs& a) {
    ConditioningOptions o;
    if (a.resample_option && a.resample_option->count() > 0) o.resample_um = a.resample_um;
    o.fill = parse_fill_method(a.fill, "--fill");
    o.detrend_order = parse_detrend(a.detrend, "--detrend");
    if (!a.crop.empty()) o.crop = parse_crop(a.crop, "--crop");
    o.periodic = parse_periodic_method(a.periodic, "--periodic");
    return o;
}

bool any_conditioning(const ConditioningArgs& a) {
    const ConditioningOptions o = to_conditioning_options(a);
    return o.resample_um || o.fill != FillMethod::Refuse || o.detrend_order >= 0 || o.crop ||
           o.periodic != PeriodicMethod::None;
}

namespace {

MeasuredSurface condition_reported(const MeasuredSurface& surface, const ConditioningArgs& args, bool quiet,
                                   std::vector<std::string>* steps) {
    ConditioningReport report;
    MeasuredSurface out = condition(surface, to_conditioning_options(args), &report);
    if (!quiet)
        for (const std::string& step : report.steps) std::fprintf(stderr, "conditioning: %s\n", step.c_str());
    if (steps) steps->insert(steps->end(), report.steps.begin(), report.steps.end());
    return out;
}

}  // namespace

MeasuredSurface condition_and_report(const MeasuredSurface& surface, const ConditioningArgs& args, bool quiet) {
    return condition_reported(surface, args, quiet, nullptr);
}

Heightfield read_conditioned_heightfield(const std::string& path, const ConditioningArgs& args,
                                         std::optional<double> spacing_um, std::optional<double> vscale, bool quiet,
                                         std::vector<std::string>& steps) {
    const ConditioningOptions checked = to_conditioning_options(args);  // bad options before reading
    (void)checked;
    const MeasuredSurface surface = condition_reported(read_surface(path, spacing_um), args, quiet, &steps);
    return to_heightfield(surface, path, std::nullopt, vscale);
}

}  // namespace wavebrdf::cli
