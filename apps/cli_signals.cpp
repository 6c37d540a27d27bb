#include "cli_signals.h"

#include <signal.h>
#include <unistd.h>

#include <atomic>

#include "wavebrdf/io.h"

namespace wavebrdf::cli {

namespace {

std::atomic<bool> g_graceful{false};
std::atomic<int> g_stop_signal{0};
std::atomic<bool> g_ended{false};
std::atomic<bool> g_stopping{false};
static_assert(std::atomic<int>::is_always_lock_free && std::atomic<bool>::is_always_lock_free,
              "the signal handler needs lock-free atomics");

// One line on stderr before the signal ends the process: under mpiexec the exit status alone
// (1) says nothing of why the run stopped. write() is async-signal-safe; printf is not.
void say_stopped(int sig) {
    const char* text = sig == SIGINT
                           ? "wavebrdf: stopped by SIGINT before the run finished; its outputs are incomplete\n"
                       : sig == SIGTERM
                           ? "wavebrdf: stopped by SIGTERM before the run finished; its outputs are incomplete\n"
                           : "wavebrdf: stopped by SIGHUP before the run finished; its outputs are incomplete\n";
    std::size_t length = 0;
    while (text[length] != '\0') ++length;
    const ssize_t written = ::write(STDERR_FILENO, text, length);
    (void)written;
}

// Only async-signal-safe calls: atomics, unlink (in remove_temporary_files), write, sigaction, raise.
extern "C" void on_signal(int sig) {
    if (sig != SIGHUP && g_graceful.load()) {
        int none = 0;
        if (g_stop_signal.compare_exchange_strong(none, sig)) return;  // the first: stop gracefully
    }
    // Set before the temporaries go: a write that sees them going fails, and the command's
    // catch then leaves the line to this handler (stopping()). Whether the command had ended
    // is read now, before its thread can end it with that failure.
    g_stopping.store(true);
    const bool ended = g_ended.load();
    remove_temporary_files();
    if (!ended) say_stopped(sig);
    struct sigaction fallback {};
    fallback.sa_handler = SIG_DFL;
    sigemptyset(&fallback.sa_mask);
    sigaction(sig, &fallback, nullptr);
    // Pending (the handler blocks it) until the handler returns, then fatal by default.
    raise(sig);
}

}  // namespace

void install_signal_cleanup() {
    struct sigaction action {};
    action.sa_handler = on_signal;
    // One handler at a time: a SIGTERM while a SIGINT is handled waits for it.
    sigemptyset(&action.sa_mask);
    for (int sig : {SIGINT, SIGTERM, SIGHUP}) sigaddset(&action.sa_mask, sig);
    action.sa_flags = SA_RESTART;
    for (int sig : {SIGINT, SIGTERM, SIGHUP}) {
        // A signal ignored by whoever started us (nohup, a background job) stays ignored.
        struct sigaction old {};
        if (sigaction(sig, nullptr, &old) == 0 && old.sa_handler == SIG_IGN) continue;
        sigaction(sig, &action, nullptr);
    }
}

void mark_command_ended() { g_ended.store(true); }

bool stopping() { return g_stopping.load(); }

GracefulStop::GracefulStop() {
    g_stop_signal.store(0);
    g_graceful.store(true);
}

GracefulStop::~GracefulStop() { g_graceful.store(false); }

int GracefulStop::signal() const { return g_stop_signal.load(); }

}  // namespace wavebrdf::cli
