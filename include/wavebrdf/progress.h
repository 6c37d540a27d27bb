#pragma once
// A progress bar for long work: drawn on stderr when stderr is a terminal, silent otherwise
// or when disabled. Thread-safe `advance`.
#include <atomic>
#include <chrono>
#include <mutex>
#include <string>

namespace wavebrdf {

// Draws `label [#####.....]  45%  12/27  0:03 eta 0:04  message` on one stderr line,
// redrawn in place ('\r') at most every 100 ms and once more, with a newline, by `finish`.
// When disabled or when stderr is not a terminal nothing at all is written, but the count
// is still kept (`done`).
class Progress {
public:
    // `total` units of work (≥ 0; std::invalid_argument otherwise); `enabled` false
    // (e.g. --quiet) keeps the bar from ever being drawn.
    Progress(std::string label, long long total, bool enabled = true);
    // Calls `finish` if it has not been called.
    ~Progress();
    Progress(const Progress&) = delete;
    Progress& operator=(const Progress&) = delete;

    // Adds `units` to the count; safe to call from several (OpenMP) threads at once. Draws
    // only if no other thread is drawing and the last draw is ≥ 100 ms old.
    void advance(long long units = 1);
    void set_message(const std::string& message);  // shown after the bar (e.g. the loss)
    // Draws the final state and ends the line; later calls do nothing.
    void finish();

    // Units counted so far (added so that tests and callers can read the count back; it
    // counts even when the bar is not drawn).
    long long done() const { return m_done.load(std::memory_order_relaxed); }

    // True when stderr is a terminal (the bar would be visible).
    static bool stderr_is_terminal();

private:
    // Writes the bar; the caller holds m_mutex.
    void draw(bool final_draw);

    std::string m_label;
    std::string m_message;
    long long m_total;
    std::atomic<long long> m_done{0};
    bool m_active;
    bool m_finished = false;
    std::mutex m_mutex;
    std::chrono::steady_clock::time_point m_start;
    std::chrono::steady_clock::time_point m_last_draw;
};

}  // namespace wavebrdf
