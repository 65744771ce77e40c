// Fuzz target: the OBJ reader, and the checks a `convex` body's mesh goes through after it.

#include "systems/obj_mesh.h"
#include "tests/fuzz/fuzz_support.h"

#include <stdexcept>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    using namespace tumble;
    try {
        const auto mesh = parseObjMesh(fuzz::text(data, size), "fuzzed.obj");
        convexHullMesh(*mesh);
    } catch (const std::runtime_error&) {
    }
    return 0;
}
