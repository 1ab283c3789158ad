// A generated static trial for the shipped gait2354 template, so that `fabrik bench fullbody`
// can calibrate the template as users do when no recorded static trial is at hand.
#pragma once

#include "io/marker_trial.hpp"

namespace fabrik::bench {

// A generic adult standing with the arms held out sideways (as OpenSim's subject01 static
// trial), every marker of config/templates/gait2354.json, `frames` frames at 60 Hz with seeded
// Gaussian noise of `noise_m` per axis. Lab axes: x anterior, y up, z to the right.
io::MarkerTrial generic_gait2354_static(int frames = 30, double noise_m = 0.3e-3,
                                        unsigned seed = 1);

}  // namespace fabrik::bench
