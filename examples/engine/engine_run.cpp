// Running a scenario file through the engine's classes: a Simulation over the built-in systems' catalog,
// stepped frame by frame, its springs read straight from the world, and the state hash printed, which is
// the one `tumble run FILE --frames N --dump OUT` writes for frame N.
//
//   engine_run SCENARIO.toml [FRAMES]        (default 60 frames)

#include "components/spring_network.h"
#include "engine/scenario.h"
#include "engine/simulation.h"
#include "systems/builtin.h"

#include <cinttypes>
#include <cstdio>
#include <exception>
#include <string>

int main(int argc, char** argv) {
    if (argc < 2) {
        std::fprintf(stderr, "usage: engine_run SCENARIO.toml [FRAMES]\n");
        return 2;
    }
    const std::string path = argv[1];
    const int frames = argc > 2 ? std::stoi(argv[2]) : 60;
    try {
        tumble::Simulation sim(tumble::builtinCatalog(), path, tumble::readScenarioFile(path), {},
                               tumble::kDefaultMemoryCap, 1);
        for (int i = 0; i < frames; ++i) {
            sim.runFrame();
        }
        // the lowest point of every spring network, read from the component itself
        sim.world().view<const tumble::SpringNetwork>().each(
            [](tumble::Entity, const tumble::SpringNetwork& net) {
                double lowest = 0.0;
                for (std::size_t i = 0; i < net.x.size(); ++i) {
                    lowest = i == 0 || net.x[i].y < lowest ? net.x[i].y : lowest;
                }
                std::printf("spring network of %zu masses, lowest at y = %.4f m\n", net.x.size(), lowest);
            });
        std::printf("hash %016" PRIx64 "\n", sim.hash());
        return 0;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "engine_run: %s\n", e.what());
        return 2;
    }
}
