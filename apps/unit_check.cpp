#include "unit_check.h"

#include <cstdio>

namespace wavebrdf::cli {

UnitCheck warn_units(const Heightfield& hf, double lambda_um, const std::string& name) {
    UnitCheck c = check_units(hf, lambda_um);
    for (const std::string& w : c.warnings) std::fprintf(stderr, "wavebrdf: warning: %s: %s\n", name.c_str(), w.c_str());
    return c;
}

void print_units(const UnitCheck& c, const std::string& name, bool quiet) {
    if (!quiet) std::fprintf(stderr, "%s: %s\n", name.c_str(), describe(c).c_str());
}

}  // namespace wavebrdf::cli
