// Fuzz target: `--set KEY=VALUE`. Each line of the input is one override of a small scene that holds one
// of every kind of entity (seeds/scenario/every_kind.toml), loaded as `check` loads it: the parser, the
// overrides applied to the TOML, and every loader's validation and memory charge. Running what loads is
// the sweep's part (tests/sweep): building Bullet, Box2D and a cloth for every input held this target to
// ~700 inputs a second, too few to search the parser.

#include "engine/scenario.h"
#include "engine/world.h"
#include "tests/fuzz/fuzz_support.h"

#include <vector>

namespace {

constexpr const char* kScenePath = TUMBLE_SOURCE_DIR "/tests/fuzz/seeds/scenario/every_kind.toml";

/// The base scene, read once.
const std::string& baseScene() {
    static const std::string text = tumble::readScenarioFile(kScenePath);
    return text;
}

} // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    using namespace tumble;
    std::vector<std::string> overrides;
    const std::string input = fuzz::text(data, size);
    for (std::size_t at = 0; at <= input.size() && overrides.size() < 16;) {
        const std::size_t end = std::min(input.find('\n', at), input.size());
        overrides.push_back(input.substr(at, end - at));
        at = end + 1;
    }
    World world;
    try {
        loadScenario(fuzz::builtinCatalog(), kScenePath, baseScene(), overrides, world, fuzz::kMemoryCap);
    } catch (const ScenarioError&) {
    }
    return 0;
}
