#include "tests/test_support.h"

#include "app/subprocess.h"
#include "systems/builtin.h"

#include <algorithm>
#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <sys/wait.h>
#include <unistd.h>

namespace tumble::test {

std::string tempPath(const std::string& name) {
    // one folder per test process, so parallel ctest runs do not collide
    static const std::string dir = [] {
        std::string d = std::string(TUMBLE_TEST_TMP) + "/" + std::to_string(::getpid());
        std::filesystem::create_directories(d);
        return d;
    }();
    const std::string p = dir + "/" + name;
    std::filesystem::remove_all(p);
    return p;
}

std::string writeTemp(const std::string& name, const std::string& text) {
    const std::string p = tempPath(name);
    std::ofstream(p, std::ios::binary) << text;
    return p;
}

std::string readFile(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    std::ostringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

const char* const kBlowingUpBob = R"(
[[entity]]
name = "bob"
[entity.springs]
integrator = "explicit_euler"
masses = [ { x = [0, 0, 0], pinned = true }, { x = [1.5, 0, 0] } ]
links = [ { a = 0, b = 1, rest = 1.0, k = 1e6 } ]
)";

std::string slideAcrossAPull(const std::string& bodyTables) {
    return R"(
[scene]
name = "slide"
dt = 0.001666666667
gravity = [0, 0, 0]
[[entity]]
name = "spring"
[entity.springs]
integrator = "symplectic_euler"
stiffness = 200.0
masses = [ { x = [0, 3, 0], m = 0.001, pinned = true }, { x = [0, 1, 0], m = 0.001 } ]
links = [ { a = 0, b = 1, rest = 1.0 } ]
[[entity]]
name = "box"
[entity.transform]
position = [0, 1, 0]
)" + bodyTables +
           R"(
[[joint]]
type = "anchor"
a = "spring"
mass = 1
b = "box"
)";
}

ProcessResult runTumble(const std::vector<std::string>& args, const std::vector<std::string>& environment) {
    const std::string errPath = tempPath("stderr.txt");
    std::string cmd;
    if (!environment.empty()) {
        cmd = "env";
        for (const std::string& e : environment) {
            cmd += " " + shellQuote(e);
        }
        cmd += " ";
    }
    cmd += shellQuote(TUMBLE_BINARY);
    for (const std::string& a : args) {
        cmd += " " + shellQuote(a);
    }
    cmd += " </dev/null 2>" + shellQuote(errPath);
    ProcessResult r;
    FILE* p = ::popen(cmd.c_str(), "r");
    if (!p) {
        return r;
    }
    std::array<char, 4096> buf;
    std::size_t n;
    while ((n = std::fread(buf.data(), 1, buf.size(), p)) > 0) {
        r.out.append(buf.data(), n);
    }
    const int status = ::pclose(p);
    r.exitCode = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    r.err = readFile(errPath);
    return r;
}

std::vector<std::string> demoNames() {
    std::vector<std::string> names;
    for (const auto& e : std::filesystem::directory_iterator(std::string(TUMBLE_SOURCE_DIR) + "/demos")) {
        if (e.path().extension() == ".toml") {
            names.push_back(e.path().stem().string());
        }
    }
    std::sort(names.begin(), names.end());
    return names;
}

const Catalog& builtinCatalog() {
    return tumble::builtinCatalog();
}

std::unique_ptr<Simulation> makeSimulation(const std::string& text,
                                           const std::vector<std::string>& overrides) {
    return std::make_unique<Simulation>(builtinCatalog(), "test.toml", text, overrides);
}

} // namespace tumble::test
