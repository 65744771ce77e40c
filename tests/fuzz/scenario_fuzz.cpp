// Fuzz target: the scenario loader. Any text becomes a loaded world or a ScenarioError.

#include "engine/scenario.h"
#include "engine/world.h"
#include "tests/fuzz/fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    using namespace tumble;
    World world;
    try {
        loadScenario(fuzz::builtinCatalog(), fuzz::scenarioPath(), fuzz::text(data, size), {}, world,
                     fuzz::kMemoryCap);
    } catch (const ScenarioError&) {
    }
    return 0;
}
