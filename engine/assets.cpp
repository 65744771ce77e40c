#include "engine/assets.h"

#include <cstdlib>
#include <filesystem>

namespace tumble {

namespace fs = std::filesystem;

std::string assetDirectory() {
    if (const char* env = std::getenv("TUMBLE_ASSETS"); env && *env) {
        return env;
    }
    std::error_code ec;
    const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
    if (!ec) {
        for (const fs::path& candidate :
             {exe.parent_path() / "assets", exe.parent_path() / ".." / "assets"}) {
            if (fs::is_directory(candidate / "shaders")) {
                return fs::weakly_canonical(candidate).string();
            }
        }
    }
    return std::string(TUMBLE_SOURCE_DIR) + "/assets";
}

} // namespace tumble
