#include "run_program.h"

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <stdexcept>

extern char** environ;

namespace wavebrdf::cli {

namespace {

int spawn_and_wait(const std::vector<std::string>& argv, char* const* environment) {
    if (argv.empty()) throw std::invalid_argument("run_program: empty argument vector; expected a program path");
    std::vector<char*> args;
    args.reserve(argv.size() + 1);
    for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
    args.push_back(nullptr);

    posix_spawn_file_actions_t actions;
    if (posix_spawn_file_actions_init(&actions) != 0) return -1;
    bool ok = posix_spawn_file_actions_addopen(&actions, STDIN_FILENO, "/dev/null", O_RDONLY, 0) == 0 &&
              posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, "/dev/null", O_WRONLY, 0) == 0;
    pid_t pid = -1;
    if (ok) ok = posix_spawn(&pid, args[0], &actions, nullptr, args.data(), environment) == 0;
    posix_spawn_file_actions_destroy(&actions);
    if (!ok) return -1;

    int status = 0;
    while (::waitpid(pid, &status, 0) < 0)
        if (errno != EINTR) return -1;
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

}  // namespace

int run_program(const std::vector<std::string>& argv) { return spawn_and_wait(argv, environ); }

int run_program(const std::vector<std::string>& argv, const std::vector<std::string>& environment) {
    std::vector<char*> env;
    env.reserve(environment.size() + 1);
    for (const std::string& e : environment) env.push_back(const_cast<char*>(e.c_str()));
    env.push_back(nullptr);
    return spawn_and_wait(argv, env.data());
}

}  // namespace wavebrdf::cli
