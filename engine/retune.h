#pragma once
// The `set` event (README, "Using it"): at a step, sets any key that `--set` may set, checked by the same
// schema with the same errors.
//
// How: the scenario is loaded twice into scratch worlds, without the change and with it (each time with the
// run's --set overrides and every set before it), and the two are compared. The scene's settings and each
// component a system registered a Retune for take, in the live world, exactly what differs between the two
// loads. So a change touches only what its key made (a cloth's `stretch` its structural springs), and what
// the run has changed since the start (an `unpin`, a `set_rate`) stays. A change the running world cannot
// take (a cloth's number of rows, the scene's dt) is refused when the scenario loads, saying why; so is one
// that adds or removes entities or components.

#include "engine/catalog.h"
#include "engine/scenario.h"
#include "engine/world.h"

#include <optional>
#include <string>
#include <vector>

namespace tumble {

/// A retune's patch, one field at a time: the live field takes `after` where it differs from `before`.
template <class T>
void takeChanged(T& live, const T& before, const T& after) {
    if (!(before == after)) {
        live = after;
    }
}

/// Whether `spec` (KEY=VALUE) can be set during a run of `scenario` after the sets `earlier`: a message when
/// it cannot (the loader's own for an unknown key or a bad value).
std::optional<std::string> checkSet(const Catalog& catalog, const Scenario& scenario,
                                    const std::vector<std::string>& earlier, const std::string& spec,
                                    std::uint64_t memoryCap);

/// Sets `spec` in the live world and scene (`checkSet` has passed): see the header comment.
void applySet(const Catalog& catalog, const Scenario& scenario, const std::vector<std::string>& earlier,
              const std::string& spec, std::uint64_t memoryCap, World& live, SceneDef& scene);

} // namespace tumble
