#pragma once
// Starting helper programs (the report plotters) without a shell.
#include <string>
#include <vector>

namespace wavebrdf::cli {

// Runs the program at path argv[0] (not searched in PATH) with arguments argv[1...] exactly as
// given, through posix_spawn: no shell, so quotes, spaces, `;` or `$(...)` in an argument are
// plain characters. stdin and stdout are /dev/null, stderr is inherited. The environment is
// this process's, or `environment` ("NAME=VALUE" strings, the whole environment) when given.
// Waits for it and returns its exit status (0 to 255), or -1 when it could not be started or
// was killed by a signal. Never throws for a failure of the program itself;
// std::invalid_argument for an empty argv.
int run_program(const std::vector<std::string>& argv);
int run_program(const std::vector<std::string>& argv, const std::vector<std::string>& environment);

}  // namespace wavebrdf::cli
