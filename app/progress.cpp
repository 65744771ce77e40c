#include "app/progress.h"

#include <algorithm>
#include <string>
#include <unistd.h>

namespace tumble {

ProgressBar::ProgressBar(std::uint64_t totalFrames, double frameSeconds, bool enabled, std::FILE* out)
    : m_total(totalFrames), m_frameSeconds(frameSeconds), m_enabled(enabled), m_out(out),
      m_start(std::chrono::steady_clock::now()), m_last(m_start) {}

ProgressBar::~ProgressBar() {
    if (m_drawn) {
        std::fputc('\n', m_out);
    }
}

bool ProgressBar::stderrIsTerminal() {
    return ::isatty(STDERR_FILENO) == 1;
}

void ProgressBar::update(std::uint64_t framesDone) {
    if (!m_enabled) {
        return;
    }
    const auto now = std::chrono::steady_clock::now();
    if (now - m_last < std::chrono::milliseconds(100)) {
        return;
    }
    m_last = now;
    draw(framesDone);
}

void ProgressBar::clearLine() {
    if (m_drawn) {
        std::fputs("\r\033[K", m_out);
        m_drawn = false;
    }
}

void ProgressBar::finish(std::uint64_t framesDone) {
    if (!m_enabled) {
        return;
    }
    draw(framesDone);
    std::fputc('\n', m_out);
    m_drawn = false;
}

void ProgressBar::draw(std::uint64_t framesDone) {
    constexpr int kWidth = 30;
    const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - m_start).count();
    const double fraction = m_total ? std::min(1.0, double(framesDone) / double(m_total)) : 1.0;
    const int filled = static_cast<int>(fraction * kWidth);
    const double msPerFrame = framesDone ? 1000.0 * elapsed / double(framesDone) : 0.0;
    const double eta =
        framesDone ? elapsed / double(framesDone) * double(m_total - std::min(m_total, framesDone)) : 0.0;
    std::string bar(std::size_t(filled), '#');
    bar.resize(kWidth, '.');
    std::fprintf(m_out, "\r[%s] frame %llu/%llu  t=%.2fs  %.2f ms/frame  ETA %.0fs   ", bar.c_str(),
                 static_cast<unsigned long long>(framesDone), static_cast<unsigned long long>(m_total),
                 double(framesDone) * m_frameSeconds, msPerFrame, eta);
    std::fflush(m_out);
    m_drawn = true;
}

} // namespace tumble
