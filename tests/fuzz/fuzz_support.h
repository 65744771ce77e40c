#pragma once
// What the fuzz targets share. Each target is one LLVMFuzzerTestOneInput: built with libFuzzer (clang,
// -DTUMBLE_FUZZ=ON) it is fuzzed; built with the ordinary suite it is linked with run_inputs.cpp and fed its
// seeds and every past finding, so that a fixed finding stays fixed in the g++ and sanitizer builds too.
//
// A target accepts the one error type its input may legitimately cause (ScenarioError, ReplayError, the
// mesh reader's std::runtime_error) and lets everything else escape: an uncaught exception, like a crash,
// a sanitizer report, a timeout or a blown memory limit, is a finding.

#include "engine/catalog.h"
#include "systems/builtin.h"

#include <cstddef>
#include <cstdint>
#include <string>

namespace tumble::fuzz {

/// The built-in systems, as the `tumble` program registers them.
inline const Catalog& builtinCatalog() {
    static const Catalog catalog = [] {
        Catalog c;
        registerBuiltinSystems(c);
        return c;
    }();
    return catalog;
}

/// The memory cap fuzzed scenes load under: far below the default, so that an input asking for a big scene
/// is refused at once rather than built (the fuzzer's speed, and its 3 GiB limit under ASan, depend on it).
inline constexpr std::uint64_t kMemoryCap = 32ull << 20;

inline std::string text(const std::uint8_t* data, std::size_t size) {
    return std::string(reinterpret_cast<const char*>(data), size);
}

/// Where the fuzzed scenarios say they are: among the demos, so that meshes resolve as the demos' do.
inline const char* scenarioPath() {
    return TUMBLE_SOURCE_DIR "/demos/fuzzed.toml";
}

} // namespace tumble::fuzz
