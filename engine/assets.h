#pragma once
// Where the program finds its data (demos, shaders, meshes): a path question, not a GL one, so that
// loading a mesh needs no renderer. The same search serves the `tumble` program in its build tree or
// installed (PREFIX/bin/tumble beside PREFIX/share/tumble/), and the library (PREFIX/lib/libtumble.so,
// and the Python module, which find PREFIX/share/tumble/ from where they are loaded), from any folder.

#include <string>

namespace tumble {

/// The folder that holds shaders and meshes: $TUMBLE_ASSETS, else dataDirectory("assets").
std::string assetDirectory();

/// `sub` (demos or assets) of the first of these that has it: PREFIX/share/tumble above the file that
/// holds this code (the program in PREFIX/bin, the library or module under PREFIX/lib; found by dladdr),
/// beside the program or one folder up (the build tree), else the source tree's.
std::string dataDirectory(const std::string& sub);

} // namespace tumble
