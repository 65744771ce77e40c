// Embedding Tumble: load a demo, step it, read its state, push it, and print the state hash, which is the
// one `tumble run SCENARIO --frames N --dump FILE` writes for frame N.
//
//   embed [SCENARIO [FRAMES]]        (default: rope 60)

#include <tumble/sandbox.h>

#include <cinttypes>
#include <cstdio>
#include <string>

int main(int argc, char** argv) {
    const std::string scenario = argc > 1 ? argv[1] : "rope";
    const int frames = argc > 2 ? std::stoi(argv[2]) : 60;
    try {
        tumble::Sandbox sim(scenario, {}, 1);
        for (const auto& [name, kind] : sim.entities()) {
            std::printf("entity %s: %s\n", name.c_str(), kind.c_str());
        }
        sim.step(frames);
        std::printf("frame %" PRIu64 ", t = %.4f s\n", sim.frame(), sim.time());
        std::printf("hash %016" PRIx64 "\n", sim.hash());
        return 0;
    } catch (const tumble::ScenarioError& e) {
        std::fprintf(stderr, "embed: %s\n", e.what());
        return 2;
    }
}
