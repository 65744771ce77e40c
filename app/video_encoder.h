#pragma once
// Video output through the ffmpeg program: raw RGBA frames are piped to it on a background thread, so
// encoding does not stall the simulation (the queue holds a few frames; only if ffmpeg falls that far
// behind does a frame wait). MP4 (H.264) or GIF (with a palette), chosen by the file's extension.

#include <condition_variable>
#include <cstdint>
#include <cstdio>
#include <deque>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace tumble {

/// Encodes frames to a video file through ffmpeg; see the header comment.
class VideoEncoder {
public:
    /// Starts ffmpeg. Throws std::runtime_error if the extension is not .mp4 or .gif, or ffmpeg is missing.
    VideoEncoder(const std::string& path, int width, int height, double framesPerSecond);
    ~VideoEncoder();
    VideoEncoder(const VideoEncoder&) = delete;
    VideoEncoder& operator=(const VideoEncoder&) = delete;

    /// Queues one frame (RGBA, top row first, width x height).
    void push(const std::vector<std::uint8_t>& rgba);
    /// Waits for every frame to be written and ffmpeg to finish; throws if it failed.
    void finish();

    const std::string& path() const { return m_path; }
    std::uint64_t frames() const { return m_frames; }

private:
    void writeLoop();

    std::string m_path;
    std::size_t m_frameBytes;
    std::FILE* m_pipe = nullptr;
    std::thread m_writer;
    std::mutex m_mutex;
    std::condition_variable m_changed;
    std::deque<std::vector<std::uint8_t>> m_queue;
    bool m_closing = false;
    bool m_failed = false;
    bool m_finished = false;
    std::uint64_t m_frames = 0;
};

} // namespace tumble
