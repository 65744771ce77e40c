#include "app/video_encoder.h"

#include <cstdlib>
#include <filesystem>
#include <stdexcept>
#include <sys/wait.h>

namespace tumble {

namespace {

constexpr std::size_t kQueueFrames = 8;

std::string quoted(const std::string& s) {
    std::string q = "'";
    for (char c : s) {
        q += c == '\'' ? std::string("'\\''") : std::string(1, c);
    }
    return q + "'";
}

} // namespace

VideoEncoder::VideoEncoder(const std::string& path, int width, int height, double framesPerSecond)
    : m_path(path), m_frameBytes(std::size_t(width) * std::size_t(height) * 4) {
    const std::string ext = std::filesystem::path(path).extension().string();
    std::string codec;
    if (ext == ".mp4") {
        // H.264 wants even sizes and 4:2:0
        codec = "-vf 'pad=ceil(iw/2)*2:ceil(ih/2)*2' -c:v libx264 -preset veryfast -crf 20 -pix_fmt yuv420p "
                "-movflags +faststart";
    } else if (ext == ".gif") {
        codec = "-vf 'split[a][b];[a]palettegen[p];[b][p]paletteuse'";
    } else {
        throw std::runtime_error("--video " + path + ": the file must end in .mp4 or .gif");
    }
    if (std::system("command -v ffmpeg >/dev/null 2>&1") != 0) {
        throw std::runtime_error("--video needs the ffmpeg program, which is not installed here "
                                 "(apt-get install ffmpeg), or run without --video");
    }
    const std::filesystem::path p(path);
    if (p.has_parent_path()) {
        std::error_code ec;
        std::filesystem::create_directories(p.parent_path(), ec);
    }
    const std::string command = "ffmpeg -hide_banner -loglevel error -y -f rawvideo -pix_fmt rgba -s " +
                                std::to_string(width) + "x" + std::to_string(height) + " -r " +
                                std::to_string(framesPerSecond) + " -i - " + codec + " " + quoted(path);
    m_pipe = ::popen(command.c_str(), "w");
    if (!m_pipe) {
        throw std::runtime_error("--video: cannot start ffmpeg");
    }
    m_writer = std::thread([this] { writeLoop(); });
}

VideoEncoder::~VideoEncoder() {
    try {
        finish();
    } catch (...) {
        // the destructor must not throw; finish() is called explicitly where errors matter
    }
}

void VideoEncoder::push(const std::vector<std::uint8_t>& rgba) {
    if (rgba.size() != m_frameBytes) {
        throw std::logic_error("video frame of the wrong size");
    }
    std::unique_lock lock(m_mutex);
    m_changed.wait(lock, [this] { return m_queue.size() < kQueueFrames || m_failed; });
    if (m_failed) {
        throw std::runtime_error("--video " + m_path + ": ffmpeg stopped taking frames");
    }
    m_queue.push_back(rgba);
    ++m_frames;
    m_changed.notify_all();
}

void VideoEncoder::writeLoop() {
    for (;;) {
        std::vector<std::uint8_t> frame;
        {
            std::unique_lock lock(m_mutex);
            m_changed.wait(lock, [this] { return !m_queue.empty() || m_closing; });
            if (m_queue.empty()) {
                return;
            }
            frame = std::move(m_queue.front());
            m_queue.pop_front();
            m_changed.notify_all();
        }
        if (std::fwrite(frame.data(), 1, frame.size(), m_pipe) != frame.size()) {
            std::lock_guard lock(m_mutex);
            m_failed = true;
            m_queue.clear();
            m_changed.notify_all();
            return;
        }
    }
}

void VideoEncoder::finish() {
    if (m_finished) {
        return;
    }
    m_finished = true;
    {
        std::lock_guard lock(m_mutex);
        m_closing = true;
        m_changed.notify_all();
    }
    if (m_writer.joinable()) {
        m_writer.join();
    }
    const int status = m_pipe ? ::pclose(m_pipe) : -1;
    m_pipe = nullptr;
    if (m_failed || status == -1 || !WIFEXITED(status) || WEXITSTATUS(status) != 0) {
        throw std::runtime_error("--video " + m_path + ": ffmpeg failed to encode the video");
    }
}

} // namespace tumble
