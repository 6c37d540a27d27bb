#pragma once
// A progress bar for long work: drawn on stderr when stderr is a terminal, silent otherwise
// or when disabled. Thread-safe `advance`.
#include <atomic>
#include <chrono>
#include <mutex>
#include <string>

namespace wavebrdf {

class Progress {
public:
    // `total` units of work; `enabled` false (e.g. --quiet) makes every call a no-op.
    Progress(std::string label, long long total, bool enabled = true);
    ~Progress();
    Progress(const Progress&) = delete;
    Progress& operator=(const Progress&) = delete;

    void advance(long long units = 1);
    void set_message(const std::string& message);  // shown after the bar (e.g. the loss)
    void finish();

    // True when stderr is a terminal (the bar would be visible).
    static bool stderr_is_terminal();

private:
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
