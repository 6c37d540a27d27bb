// wavebrdf: the command-line tool. Thin: parse arguments, call the library, map errors to a
// one-line message and a non-zero exit.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <exception>
#include <iostream>
#include <string>
#include <vector>

#include "cli_common.h"
#include "cli_signals.h"
#include "commands.h"
#include "wavebrdf/communicator.h"
#include "wavebrdf/version.h"

int main(int argc, char** argv) {
    // Before any output is written: a signal must not leave temporary files behind.
    wavebrdf::cli::install_signal_cleanup();
    CLI::App app{"wavebrdf: wave-optical BRDFs of microscale heightfields"};
    app.require_subcommand(1);
    app.set_version_flag("--version", std::string("wavebrdf ") + wavebrdf::k_version);
    wavebrdf::cli::add_heightfield_command(app);
    wavebrdf::cli::add_render_command(app);
    wavebrdf::cli::add_genbrdf_command(app);
    wavebrdf::cli::add_invert_command(app);
    wavebrdf::cli::add_recover_command(app);
    wavebrdf::cli::add_table_command(app);
    wavebrdf::cli::add_convert_command(app);
    wavebrdf::cli::add_stats_command(app);
    wavebrdf::cli::add_lobe_command(app);
    wavebrdf::cli::add_image_command(app);
    wavebrdf::cli::add_design_command(app);
    app.footer(wavebrdf::cli::k_common_help);
    // What every command shares: --threads, and the help's last lines (after the command's own).
    for (CLI::App* command : app.get_subcommands([](CLI::App*) { return true; })) {
        wavebrdf::cli::add_threads_option(command);
        const std::string own = command->get_footer();
        command->footer(own.empty() ? std::string(wavebrdf::cli::k_common_help)
                                    : own + "\n" + wavebrdf::cli::k_common_help);
    }
    // CLI11's own errors (unknown option, bad number, missing value) in the same one-line form
    // as the commands' errors; --help and --version are not failures and print as usual.
    // A misspelt option or command gets the nearest name ("did you mean --sigma-p-um?").
    const std::vector<std::string> args(argv + 1, argv + argc);
    app.failure_message([&app, &args](const CLI::App*, const CLI::Error& e) {
        return "wavebrdf: error: " + std::string(e.what()) + wavebrdf::cli::did_you_mean(app, e.what(), args) +
               " (see --help)\n";
    });
    // Started by mpiexec (docs/scale.md): every rank parses the same arguments and fails alike;
    // rank 0 alone prints (help, version, errors).
    const bool quiet_rank = wavebrdf::world_communicator()->rank() != 0;
    const int status = [&]() -> int {
        try {
            app.parse(argc, argv);
        } catch (const CLI::ParseError& e) {
            if (quiet_rank) return e.get_exit_code();
            return app.exit(e);
        } catch (const wavebrdf::RankFailed& e) {
            // Agreed on every rank (run_on_world prints these itself): rank 0 says why.
            if (!quiet_rank) std::cerr << "wavebrdf: error: " << e.what() << "\n";
            return 1;
        } catch (const wavebrdf::cli::ExitStatus& e) {
            return e.code;
        } catch (const std::exception& e) {
            // Errors raised by the commands themselves (they run from parse callbacks); one
            // caused by a signal being handled is left to the handler's line.
            if (!wavebrdf::cli::stopping()) std::cerr << "wavebrdf: error: " << e.what() << "\n";
            return 1;
        }
        return 0;
    }();
    wavebrdf::cli::mark_command_ended();
    return status;
}
