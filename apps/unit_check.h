#pragma once
// The unit check every command makes of the heightfield it reads or makes (docs/model.md,
// "Where the model holds"; docs/cli.md, "The unit check").
#include <string>

#include "wavebrdf/heightfield.h"
#include "wavebrdf/model.h"
#include "wavebrdf/surface_stats.h"

namespace wavebrdf::cli {

// check_units(heightfield, lambda_um) (surface_stats.h), its warnings printed on stderr at once
// as "wavebrdf: warning: <name>: …" (before the command's work, which they may make futile).
UnitCheck warn_units(const Heightfield& heightfield, double lambda_um, const std::string& name);
// The same for the footprint of one slice (check_units_footprint): what a footprint read of a
// file holds, and all the slice sees.
UnitCheck warn_units(const Heightfield& heightfield, const Query& footprint, double lambda_um,
                     const std::string& name);

// Prints "<name>: rms height … um, rms slope …, phase rms … rad at λ um" on stderr unless
// `quiet`: after the command's work, beside its summary (a failed command prints its one error
// line alone).
void print_units(const UnitCheck& check, const std::string& name, bool quiet);

}  // namespace wavebrdf::cli
