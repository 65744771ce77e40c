// The air solver's loops compiled for AVX2: systems/air_solver.cpp again, in namespace air_avx2 (that
// file's head says why and how the two give the same bits).
#define TUMBLE_AIR_AVX2 1
#include "systems/air_solver.cpp" // NOLINT(bugprone-suspicious-include)
