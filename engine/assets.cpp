#include "engine/assets.h"

#include <cstdlib>
#include <dlfcn.h>
#include <filesystem>
#include <vector>

namespace tumble {

namespace fs = std::filesystem;

namespace {

/// What marks a folder as the one sought: demos hold .toml files, assets hold shaders.
bool holds(const fs::path& dir, const std::string& sub) {
    std::error_code ec;
    return sub == "assets" ? fs::is_directory(dir / "shaders", ec) : fs::is_directory(dir, ec);
}

/// The folders data may sit under, in the order they are tried: first PREFIX/share/tumble above the
/// file that holds this code (libtumble.so or the Python module in PREFIX/lib/..., the program itself in
/// PREFIX/bin), found by dladdr; then beside the program or one folder up (the build tree). The library's
/// own place comes first so that a program embedding it, with a demos/ folder of its own beside it, still
/// gets Tumble's.
std::vector<fs::path> dataRoots() {
    std::vector<fs::path> roots;
    std::error_code ec;
    Dl_info info{};
    if (::dladdr(reinterpret_cast<void*>(&dataRoots), &info) != 0 && info.dli_fname) {
        for (fs::path up = fs::absolute(info.dli_fname, ec).parent_path(); up.has_relative_path();
             up = up.parent_path()) {
            roots.push_back(up / "share" / "tumble");
        }
    }
    const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
    if (!ec) {
        roots.insert(roots.end(), {exe.parent_path(), exe.parent_path() / ".."});
    }
    return roots;
}

} // namespace

std::string dataDirectory(const std::string& sub) {
    for (const fs::path& root : dataRoots()) {
        if (holds(root / sub, sub)) {
            return fs::weakly_canonical(root / sub).string();
        }
    }
    return std::string(TUMBLE_SOURCE_DIR) + "/" + sub;
}

std::string assetDirectory() {
    if (const char* env = std::getenv("TUMBLE_ASSETS"); env && *env) {
        // without a trailing separator: its parent is the project's root (meshes named "assets/...")
        std::string dir = env;
        while (dir.size() > 1 && dir.back() == '/') {
            dir.pop_back();
        }
        return dir;
    }
    return dataDirectory("assets");
}

} // namespace tumble
