#pragma once
// `tumble view`: a live window on a scene. GLFW opens the window with an EGL context, so the same GLES 3
// renderer that draws headless frames draws it; the frame is drawn offscreen and copied to the window, and
// Dear ImGui draws the budget overlay on top. Time is the fixed-step loop's, paced by the wall clock (times
// the slow-motion factor, stopped while paused), and frames are drawn between the last two steps.
//
// Every input that touches the simulation (grab, drag, release, set_integrator) is an event at the step it
// applies to, so --record writes a replay that `tumble replay --verify` plays back headlessly; the camera,
// pause, slow motion and wireframe change only what is seen. Without a display, view says so and suggests
// `run`.

#include "app/cli.h"
#include "engine/catalog.h"

namespace tumble {

/// Runs the viewer until its window closes (or Q / Esc); returns the process exit code.
int runViewer(const Catalog& catalog, const ViewRequest& request);

} // namespace tumble
