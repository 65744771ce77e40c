#pragma once
// Problems a run meets after it has started (a spring network that blew up, say). Systems append a
// message and carry on; the command line prints each one as it appears and exits 1 at the end of a run
// that had any.

#include <string>
#include <vector>

namespace tumble {

/// A world resource: what went wrong during the run, in the order it happened.
struct RunReport {
    std::vector<std::string> failures; ///< make the run exit 1
    std::vector<std::string> notes;    ///< said, but expected by the scene (e.g. on_blow_up = "freeze")
};

/// A world resource: checks a run makes on itself, asked for on the command line.
struct RunChecks {
    bool contact =
        false; ///< --check-contact: an exact crossing audit of self-colliding cloth after every step
};

} // namespace tumble
