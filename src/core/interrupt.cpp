#include "wavebrdf/interrupt.h"

#include <utility>

namespace wavebrdf {

namespace {
// The calling thread's innermost scope. OpenMP worker threads have none, so only the thread
// that called into the library polls (the Python poll needs the main thread for signals).
thread_local InterruptScope* t_scope = nullptr;
}  // namespace

InterruptScope::InterruptScope(std::function<bool()> poll, std::chrono::milliseconds interval)
    : m_poll(std::move(poll)),
      m_interval(std::chrono::milliseconds(interval.count() < 0 ? 0 : interval.count())),
      m_last(std::chrono::steady_clock::now()),
      m_outer(t_scope) {
    t_scope = this;
}

InterruptScope::~InterruptScope() { t_scope = m_outer; }

void check_interrupt() {
    InterruptScope* scope = t_scope;
    if (!scope) return;
    if (scope->m_stopped) throw Interrupted();
    const auto now = std::chrono::steady_clock::now();
    if (now - scope->m_last < scope->m_interval) return;
    scope->m_last = now;
    if (scope->m_poll && scope->m_poll()) {
        scope->m_stopped = true;
        throw Interrupted();
    }
}

}  // namespace wavebrdf
