#pragma once
// The name an entity has in its scenario; dumps, events and messages use it.

#include <string>

namespace tumble {

/// Unique name of an entity within its scene.
struct Name {
    std::string value;
};

} // namespace tumble
