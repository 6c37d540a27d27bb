#include "wavebrdf/progress.h"

#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <stdexcept>
#include <utility>

namespace wavebrdf {

namespace {

constexpr int k_bar_width = 30;
constexpr auto k_redraw_interval = std::chrono::milliseconds(100);

// m:ss, or h:mm:ss from one hour on.
std::string format_duration(double seconds) {
    long long s = static_cast<long long>(std::max(0.0, seconds) + 0.5);
    char buf[32];
    if (s >= 3600)
        std::snprintf(buf, sizeof buf, "%lld:%02lld:%02lld", s / 3600, (s / 60) % 60, s % 60);
    else
        std::snprintf(buf, sizeof buf, "%lld:%02lld", s / 60, s % 60);
    return buf;
}

}  // namespace

Progress::Progress(std::string label, long long total, bool enabled)
    : m_label(std::move(label)),
      m_total(total),
      m_active(enabled && stderr_is_terminal()),
      m_start(std::chrono::steady_clock::now()),
      m_last_draw(m_start) {
    if (total < 0)
        throw std::invalid_argument("progress total " + std::to_string(total) +
                                    " is negative; expected >= 0 units of work");
    if (m_active) {
        std::lock_guard<std::mutex> lock(m_mutex);
        draw(false);
    }
}

Progress::~Progress() { finish(); }

bool Progress::stderr_is_terminal() { return ::isatty(STDERR_FILENO) == 1; }

void Progress::advance(long long units) {
    m_done.fetch_add(units, std::memory_order_relaxed);
    if (!m_active) return;
    // Never block a worker thread: whoever finds the lock free draws, the others go on.
    std::unique_lock<std::mutex> lock(m_mutex, std::try_to_lock);
    if (!lock.owns_lock() || m_finished) return;
    if (std::chrono::steady_clock::now() - m_last_draw < k_redraw_interval) return;
    draw(false);
}

void Progress::set_message(const std::string& message) {
    if (!m_active) return;
    std::lock_guard<std::mutex> lock(m_mutex);
    m_message = message;
    if (!m_finished && std::chrono::steady_clock::now() - m_last_draw >= k_redraw_interval) draw(false);
}

void Progress::finish() {
    std::lock_guard<std::mutex> lock(m_mutex);
    if (m_finished) return;
    m_finished = true;
    if (m_active) draw(true);
}

void Progress::draw(bool final_draw) {
    const auto now = std::chrono::steady_clock::now();
    m_last_draw = now;
    const long long done = std::min(m_done.load(std::memory_order_relaxed), m_total);
    const double fraction = m_total > 0 ? static_cast<double>(std::max(done, 0LL)) / static_cast<double>(m_total) : 1.0;
    const int filled = std::clamp(static_cast<int>(fraction * k_bar_width), 0, k_bar_width);
    const double elapsed = std::chrono::duration<double>(now - m_start).count();

    std::string line = "\r" + m_label + " [";
    line.append(static_cast<std::size_t>(filled), '#');
    line.append(static_cast<std::size_t>(k_bar_width - filled), '.');
    char buf[96];
    std::snprintf(buf, sizeof buf, "] %3d%%  %lld/%lld  ", static_cast<int>(fraction * 100.0), done, m_total);
    line += buf;
    line += format_duration(elapsed);
    // Remaining time from the mean rate so far; unknown before the first unit is done.
    if (!final_draw) {
        line += " eta ";
        line += done > 0 ? format_duration(elapsed * static_cast<double>(m_total - done) / static_cast<double>(done))
                         : std::string("-:--");
    }
    if (!m_message.empty()) line += "  " + m_message;
    line += "\x1b[K";  // clear what a longer previous line left behind
    if (final_draw) line += '\n';
    std::fwrite(line.data(), 1, line.size(), stderr);
    std::fflush(stderr);
}

}  // namespace wavebrdf
