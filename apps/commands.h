#pragma once
// The subcommands of the wavebrdf tool; each registers itself and runs from a callback.
#include <CLI/CLI.hpp>

namespace wavebrdf::cli {

// Thrown by a command (from its callback) to end the tool with `code` once its outputs are
// written, e.g. 128 + SIGINT for a run stopped by a signal; main returns it.
struct ExitStatus {
    int code = 0;
};

void add_heightfield_command(CLI::App& app);  // wavebrdf heightfield: procedural surfaces
void add_render_command(CLI::App& app);       // wavebrdf render: one BRDF slice
void add_genbrdf_command(CLI::App& app);      // wavebrdf genbrdf: the reference's flags
void add_invert_command(CLI::App& app);       // wavebrdf invert: the inverse renderer
void add_recover_command(CLI::App& app);      // wavebrdf recover: heights from overlapping slices
void add_table_command(CLI::App& app);        // wavebrdf table: slices over a grid of lights
void add_convert_command(CLI::App& app);      // wavebrdf convert: surface files, conditioned
void add_stats_command(CLI::App& app);        // wavebrdf stats: ISO 25178-2 parameters, PSD, ACF
void add_lobe_command(CLI::App& app);         // wavebrdf lobe: an analytic lobe as a table
void add_image_command(CLI::App& app);        // wavebrdf image: camera pictures of the surface
void add_design_command(CLI::App& app);      // wavebrdf design: a relief for a target appearance

}  // namespace wavebrdf::cli
