#pragma once
// The scene-wide settings of a scenario ([scene], [budget], [camera], [render]) and the scripted events.

#include "engine/entity.h"

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace tumble {

/// Settings that hold for the whole run; read once from the scenario, never changed by systems.
struct SceneDef {
    std::string name;
    std::string description;
    double dt = 1.0 / 60.0;                         ///< s, fixed physics step
    int substeps = 1;                               ///< fixed steps per frame
    std::int64_t frames = 600;                      ///< default run length
    std::array<double, 3> gravity{0.0, -9.81, 0.0}; ///< m/s^2
    std::uint64_t seed = 1;
    int solverIterations = 10; ///< Bullet's constraint solver iterations per step
    /// A Bullet body may sleep once it has moved slower than these for sleepTime (Box2D's own, 2.4.1's
    /// compiled-in 0.01 m/s, 2 degrees/s and 0.5 s, hold for Box2D bodies); an island sleeps as a whole.
    double sleepLinear = 0.05;    ///< m/s
    double sleepAngularDeg = 2.0; ///< degrees/s
    double sleepTime = 0.5;       ///< s
    int velocityIterations = 8;   ///< Box2D's velocity iterations per step
    int positionIterations = 3;   ///< Box2D's position iterations per step
    double physicsBudgetMs = 8.0; ///< per frame, held to p99 by `tumble budget`
    bool stress = false;          ///< [budget] stress = true: a scene that shows where the budget breaks
    std::array<double, 3> cameraEye{0.0, 1.5, 5.0};
    std::array<double, 3> cameraTarget{0.0, 1.0, 0.0};
    double cameraFovDeg = 45.0;
    int renderWidth = 1280;
    int renderHeight = 720;
    int renderSamples = 4;     ///< [render] msaa: samples per pixel, resolved before read-back (1: none)
    bool renderShadows = true; ///< [render] shadows: the key light's shadow map
    /// [render] light_direction: where the key light shines (unit); unset, from above and behind the camera
    std::optional<std::array<double, 3>> lightDirection;
    bool renderSkyGradient = true; ///< [render] sky_gradient: the sky pales from the zenith to the horizon
    bool renderHemisphere = true; ///< [render] hemisphere_ambient: ambient coloured by the sky and the ground
    bool renderGamma = true;      ///< [render] gamma: lit in linear light, written as sRGB
    std::array<double, 3> background{0.62, 0.74, 0.86}; ///< RGB in [0, 1], the sky behind everything

    /// Simulated time of one frame, s.
    double frameSeconds() const { return dt * substeps; }
};

/// One scripted input: an action on a named entity at a fixed step. An event at time t applies at the start
/// of the first step whose time reaches t (a step within a millionth of t counts as reaching it, so a dt
/// written with few digits still lands `at = 2.0` on the step at 2 s).
struct EventDef {
    std::uint64_t step = 0; ///< the fixed step at whose start it applies
    std::string entity;
    std::string action;
    Entity target;                    ///< the entity, resolved when the scenario loads
    std::size_t actionIndex = 0;      ///< which of the catalog's actions applies, resolved at load
    std::vector<double> value;        ///< the `value` key: one number or an array of numbers
    std::array<double, 3> position{}; ///< the `position` key (disturb)
    double radius = 0.0;              ///< the `radius` key (disturb), m
    double amount = 0.0;              ///< the `amount` key (disturb), m
    std::string set;          ///< action "set": KEY=VALUE, as --set takes it (no entity: KEY names it)
    int line = 0, column = 0; ///< where the scenario gives it (0: not from the scenario file)
};

} // namespace tumble
