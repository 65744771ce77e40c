// `tumble view` as a person uses it: under Xvfb, driven by synthetic mouse and keys (xdotool), a drag on a
// cloth is recorded, the replay verifies headlessly and shows the vertex moved, and a screenshot of the
// window shows the scene and the overlay. Without a display, view says so.
//
// Needs Xvfb, xdotool and ImageMagick's import (scripts/bootstrap.sh installs them); without them the test
// fails and says what is missing, rather than passing without having looked.

#include "components/spring_network.h"
#include "engine/render_output.h"
#include "engine/replay.h"
#include "systems/render_system.h"
#include "tests/test_support.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <stb/stb_image.h>

#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <sys/wait.h>
#include <thread>
#include <unistd.h>

namespace tumble {
namespace {

namespace fs = std::filesystem;
using test::runTumble;

/// A hanging cloth seen from the side, so that a drag across the screen pulls it out of its plane; two steps
/// a frame, so that events land inside frames and the replay's frames are whole ones.
constexpr const char* kScene = R"([scene]
name = "viewer"
dt = 0.00833333333
substeps = 2
frames = 600
[camera]
eye = [1.5, 1.6, 3.0]
target = [0.0, 1.0, 0.0]
[render]
width = 960
height = 640
[[entity]]
name = "cloth"
[entity.transform]
position = [0.0, 1.0, 0.0]
[entity.cloth]
rows = 12
cols = 12
size = [1.5, 1.5]
plane = "xy"
pin = "top-row"
integrator = "implicit_euler"
)";

bool haveTool(const std::string& name) {
    return std::system(("command -v " + name + " >/dev/null 2>&1").c_str()) == 0;
}

/// A child process in its own process group, killed with the group when it goes out of scope.
class Child {
public:
    Child(const std::string& command, const std::string& display) {
        m_pid = ::fork();
        if (m_pid == 0) {
            ::setpgid(0, 0);
            if (!display.empty()) {
                ::setenv("DISPLAY", display.c_str(), 1);
            }
            ::execl("/bin/sh", "sh", "-c", command.c_str(), static_cast<char*>(nullptr));
            ::_exit(127);
        }
        ::setpgid(m_pid, m_pid); // here too, so that the group exists before anyone kills it
    }
    ~Child() {
        if (m_pid > 0 && !m_done) {
            // politely first, so that an X server removes its lock file
            ::kill(-m_pid, SIGTERM);
            if (wait(3.0) < 0) {
                ::kill(-m_pid, SIGKILL);
                ::waitpid(m_pid, nullptr, 0);
            }
        }
    }
    Child(const Child&) = delete;
    Child& operator=(const Child&) = delete;

    void terminate() { ::kill(-m_pid, SIGTERM); }

    /// The exit code, or -1 if it did not end within the time.
    int wait(double seconds) {
        const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
        while (!m_done && std::chrono::steady_clock::now() < end) {
            int status = 0;
            if (::waitpid(m_pid, &status, WNOHANG) == m_pid) {
                m_done = true;
                m_exit = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
                break;
            }
            std::this_thread::sleep_for(std::chrono::milliseconds(50));
        }
        return m_done ? m_exit : -1;
    }

private:
    pid_t m_pid = -1;
    bool m_done = false;
    int m_exit = -1;
};

/// Runs a shell command with DISPLAY set, for 30 s at most (its first command: a viewer that died once left
/// an X tool waiting, and the test with it, for 19 minutes); its stdout.
std::string shell(const std::string& command, const std::string& display) {
    std::string out;
    FILE* p = ::popen(("DISPLAY=" + display + " timeout 30 " + command).c_str(), "r");
    if (!p) {
        return out;
    }
    char buf[512];
    while (std::fgets(buf, sizeof buf, p)) {
        out += buf;
    }
    ::pclose(p);
    return out;
}

/// A display number no X server holds.
int freeDisplay() {
    for (int n = 90 + ::getpid() % 400;; ++n) {
        if (!fs::exists("/tmp/.X" + std::to_string(n) + "-lock") &&
            !fs::exists("/tmp/.X11-unix/X" + std::to_string(n))) {
            return n;
        }
    }
}

/// A network's positions at a frame of a dump written with --dump-every 1.
std::vector<std::array<double, 3>> positionsAt(const std::string& dumpPath, const std::string& entity,
                                               std::uint64_t frame) {
    std::ifstream in(dumpPath);
    std::string line;
    while (std::getline(in, line)) {
        const nlohmann::json j = nlohmann::json::parse(line);
        if (j["frame"].get<std::uint64_t>() == frame) {
            return j["entities"][entity]["x"].get<std::vector<std::array<double, 3>>>();
        }
    }
    ADD_FAILURE() << "no frame " << frame << " in " << dumpPath;
    return {};
}

TEST(ViewerRenders, DragOnAClothIsRecordedAndTheReplayVerifiesHeadlessly) {
    for (const char* tool : {"Xvfb", "xdotool", "import"}) {
        ASSERT_TRUE(haveTool(tool)) << tool
                                    << " is missing: scripts/bootstrap.sh installs xvfb, xdotool and "
                                       "imagemagick";
    }
    const std::string dir = test::tempPath("viewer");
    fs::create_directories(dir);
    const std::string scene = dir + "/viewer.toml", replay = dir + "/drag.tumble",
                      profile = dir + "/profile.json", shot = dir + "/window.png";
    std::ofstream(scene) << kScene;
    const std::string display = ":" + std::to_string(freeDisplay());
    Child xvfb("exec Xvfb " + display + " -screen 0 1280x800x24 -nolisten tcp >/dev/null 2>&1", "");
    for (int i = 0; i < 100 && !fs::exists("/tmp/.X11-unix/X" + display.substr(1)); ++i) {
        std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    ASSERT_TRUE(fs::exists("/tmp/.X11-unix/X" + display.substr(1))) << "Xvfb " << display << " did not start";

    // the viewer, paused, so that the cloth is where the scenario puts it when the click lands
    Child view(std::string("exec ") + TUMBLE_BINARY + " view " + scene + " --paused --record " + replay +
                   " --profile " + profile + " >" + dir + "/view.out 2>" + dir + "/view.err",
               display);
    const std::string window = shell("xdotool search --sync --name 'tumble view: viewer' | head -1", display);
    ASSERT_FALSE(window.empty()) << "no window appeared; " << test::readFile(dir + "/view.err");
    const std::string id = window.substr(0, window.find('\n'));

    // the pixel of a free mass near the cloth's lower edge, as the renderer's camera projects it
    auto sim = test::makeSimulation(kScene);
    const SpringNetwork& cloth = test::component<SpringNetwork>(*sim, "cloth");
    const std::size_t vertex = 10 * 12 + 6; // row 10 of 12, the middle column
    const auto vp = viewProjection(sim->scene());
    const Vec3 p = cloth.x[vertex];
    const double cw = vp[3] * p.x + vp[7] * p.y + vp[11] * p.z + vp[15];
    const int px =
        int(std::lround((vp[0] * p.x + vp[4] * p.y + vp[8] * p.z + vp[12]) / cw * 0.5 * 960 + 480));
    const int py =
        int(std::lround((1.0 - (vp[1] * p.x + vp[5] * p.y + vp[9] * p.z + vp[13]) / cw) * 0.5 * 640));

    // press on it, run, drag up and to the right for a second, let go, look, quit
    shell("xdotool mousemove --window " + id + " " + std::to_string(px) + " " + std::to_string(py) +
              " sleep 0.4 mousedown 1 sleep 0.3 key space",
          display);
    for (int i = 0; i < 20; ++i) {
        shell("xdotool mousemove_relative -- 4 -6 sleep 0.05", display);
    }
    shell("xdotool sleep 1.0 mouseup 1 sleep 0.5", display);
    shell("import -window " + id + " " + shot, display);
    shell("xdotool key q", display); // the pointer is over the window, which takes the keys
    if (view.wait(10) < 0) {
        view.terminate(); // the key got lost: SIGTERM closes the viewer as Q does
    }
    ASSERT_EQ(view.wait(30), 0) << test::readFile(dir + "/view.err");

    // the replay holds the hold, the drags and the release, and verifies headlessly
    const ReplayFile file = readReplay(replay);
    std::size_t grabs = 0, drags = 0, releases = 0;
    std::uint32_t held = 0;
    std::uint64_t releasedAt = 0; // the frame whose steps let go
    for (std::size_t f = 0; f < file.frames.size(); ++f) {
        for (const EventDef& ev : file.frames[f].events) {
            if (ev.action == "grab") {
                ++grabs;
                held = static_cast<std::uint32_t>(ev.value.at(0));
                EXPECT_EQ(ev.entity, "cloth");
            }
            drags += ev.action == "drag";
            if (ev.action == "release") {
                ++releases;
                releasedAt = f + 1;
            }
        }
    }
    ASSERT_EQ(grabs, 1u) << "the click did not hold the cloth";
    EXPECT_GE(drags, 3u);
    ASSERT_EQ(releases, 1u);
    EXPECT_LE(std::abs(int(held) - int(vertex)), 13) << "held mass " << held << ", clicked near " << vertex;
    const auto verify = runTumble({"replay", replay, "--verify", "--no-render", "--quiet"});
    EXPECT_EQ(verify.exitCode, 0) << verify.err;

    // while held, the vertex is far from where the same frames leave it untouched
    const std::string frames = std::to_string(file.frames.size());
    ASSERT_EQ(runTumble({"replay", replay, "--no-render", "--quiet", "--dump", dir + "/dragged.jsonl",
                         "--dump-every", "1"})
                  .exitCode,
              0);
    ASSERT_EQ(runTumble({"run", scene, "--frames", frames, "--no-render", "--quiet", "--dump",
                         dir + "/still.jsonl", "--dump-every", "1"})
                  .exitCode,
              0);
    const auto dragged = positionsAt(dir + "/dragged.jsonl", "cloth", releasedAt - 1);
    const auto still = positionsAt(dir + "/still.jsonl", "cloth", releasedAt - 1);
    ASSERT_GT(dragged.size(), held);
    ASSERT_GT(still.size(), held);
    const double moved = std::hypot(dragged[held][0] - still[held][0], dragged[held][1] - still[held][1],
                                    dragged[held][2] - still[held][2]);
    EXPECT_GT(moved, 0.1) << "the dragged vertex moved " << moved << " m";

    // the profile: the mouse spring is one more system of the fixed phase (what it costs is measured by
    // the benchmark BM_CurtainRunHeld, not here: a shared machine's timings prove nothing in a test)
    const nlohmann::json summary = nlohmann::json::parse(test::readFile(profile));
    bool found = false;
    for (const auto& s : summary["systems"]) {
        if (s["name"] == "mouse_spring") {
            found = true;
            EXPECT_EQ(s["phase"], "fixed");
            EXPECT_GT(s["calls"].get<int>(), 0);
        }
    }
    EXPECT_TRUE(found) << summary.dump();

    // the screenshot: the overlay (ImGui's dark panel with white text) at the top left, the scene (the sky
    // and the cloth's red) beside it
    int w = 0, h = 0, channels = 0;
    unsigned char* pixels = stbi_load(shot.c_str(), &w, &h, &channels, 3);
    ASSERT_NE(pixels, nullptr) << "no screenshot";
    auto count = [&](int x0, int y0, int x1, int y1, auto&& test) {
        int n = 0;
        for (int y = y0; y < y1; ++y) {
            for (int x = x0; x < x1; ++x) {
                const unsigned char* c = pixels + (std::size_t(y) * std::size_t(w) + std::size_t(x)) * 3;
                n += test(int(c[0]), int(c[1]), int(c[2])) ? 1 : 0;
            }
        }
        return n;
    };
    const int panel = 200 * 120;
    const int dark = count(12, 30, 212, 150, [](int r, int g, int b) { return r < 70 && g < 70 && b < 90; });
    const int text =
        count(12, 30, 212, 150, [](int r, int g, int b) { return r > 200 && g > 200 && b > 200; });
    EXPECT_GT(dark, panel / 3) << "no overlay panel at the top left";
    EXPECT_GT(text, 100) << "no overlay text";
    const int region = (960 - 320) * 640;
    // the sky: the background's blue, paler towards the horizon (the grey floor and the red cloth are not)
    const int sky = count(320, 0, 960, 640, [](int r, int g, int b) { return b > r + 25 && b > g; });
    const int red = count(320, 0, 960, 640, [](int r, int g, int b) { return r > g + 30 && r > b + 30; });
    EXPECT_GT(sky, region / 4) << "no sky";
    EXPECT_GT(red, 2000) << "no cloth";
    stbi_image_free(pixels);
}

TEST(ViewerRenders, WithoutADisplayViewSaysSoAndSuggestsRun) {
    const auto r = runTumble({"view", "curtain"}, {"-u", "DISPLAY", "-u", "WAYLAND_DISPLAY"});
    EXPECT_EQ(r.exitCode, 1) << r.err;
    EXPECT_NE(r.err.find("needs a display"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("tumble run"), std::string::npos) << r.err;
    // a bad scenario is still the scenario's fault (exit 2), display or not
    EXPECT_EQ(runTumble({"view", "no_such_demo"}, {"-u", "DISPLAY"}).exitCode, 2);
}

} // namespace
} // namespace tumble
