#pragma once
// Stopping long work early. A caller (the Python module on Ctrl-C, a program with a signal
// flag) installs a poll with InterruptScope; the library's long loops poll it on the calling
// thread between pieces of work (rows of a slice, chunks of kernels, column blocks), at most
// every `interval`, and once it says stop they skip the rest of their parallel region and throw
// Interrupted after it. Without a scope nothing is polled and nothing changes.
#include <chrono>
#include <functional>
#include <stdexcept>

namespace wavebrdf {

// Thrown by a long library call whose poll asked it to stop; what() is "interrupted".
class Interrupted : public std::runtime_error {
public:
    Interrupted() : std::runtime_error("interrupted") {}
};

// Installs `poll` for the calling thread for the scope's lifetime: it returns true to stop the
// work (and may throw: its exception then ends the work the same way, after the parallel
// region). `interval`: least time between two polls (≥ 0). Scopes nest; the innermost applies
// and the outer one is restored on destruction. Create and destroy on the same thread.
class InterruptScope {
public:
    explicit InterruptScope(std::function<bool()> poll,
                            std::chrono::milliseconds interval = std::chrono::milliseconds(50));
    ~InterruptScope();
    InterruptScope(const InterruptScope&) = delete;
    InterruptScope& operator=(const InterruptScope&) = delete;

private:
    friend void check_interrupt();
    std::function<bool()> m_poll;
    std::chrono::steady_clock::duration m_interval;
    std::chrono::steady_clock::time_point m_last;
    InterruptScope* m_outer;
    bool m_stopped = false;
};

// Polls the calling thread's InterruptScope when one is installed and `interval` has passed
// since its last poll; throws Interrupted when the poll says stop (and on every later call in
// that scope, without polling again). Costs a clock read with a scope and a thread-local read
// without one, so kernels may call it once per row or column.
void check_interrupt();

}  // namespace wavebrdf
