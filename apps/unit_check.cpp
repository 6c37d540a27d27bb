#include "unit_check.h"

#include <cstdio>

namespace wavebrdf::cli {

namespace {

UnitCheck warn(UnitCheck c, const std::string& name) {
    for (const std::string& w : c.warnings) std::fprintf(stderr, "wavebrdf: warning: %s: %s\n", name.c_str(), w.c_str());
    return c;
}

}  // namespace

UnitCheck warn_units(const Heightfield& hf, double lambda_um, const std::string& name) {
    return warn(check_units(hf, lambda_um), name);
}

UnitCheck warn_units(const Heightfield& hf, const Query& q, double lambda_um, const std::string& name) {
    return warn(check_units_footprint(hf, q.x_um, q.y_um, q.sigma_p_um, lambda_um), name);
}

void print_units(const UnitCheck& c, const std::string& name, bool quiet) {
    if (!quiet) std::fprintf(stderr, "%s: %s\n", name.c_str(), describe(c).c_str());
}

}  // namespace wavebrdf::cli
