#pragma once
// Where the program finds its assets (shaders, meshes): a path question, not a GL one, so that loading a
// mesh needs no renderer.

#include <string>

namespace tumble {

/// The folder that holds shaders and meshes: $TUMBLE_ASSETS, else assets/ beside or above the executable,
/// else the source tree's assets/.
std::string assetDirectory();

} // namespace tumble
