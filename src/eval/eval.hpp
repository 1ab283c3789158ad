// Accuracy evaluations behind `fabrik eval`: marker residuals on a recorded
// trial (walk), gap filling against withheld real markers (gaps), joint-centre
// deviation with fewer markers (reduction), joint-centre error against
// synthetic truth (synthetic) and joint angles against a reference such as
// OpenSim's inverse kinematics (angles). Every evaluation tracks through the
// daemon's Tracker (same targets, priorities and solver settings as fabrikd),
// so the numbers are the daemon's numbers. Results are values (metres,
// radians); tables, JSON and CSV are written by tables.hpp.
#pragma once

#include "angles.hpp"
#include "gaps.hpp"
#include "imu.hpp"
#include "markerless.hpp"
#include "reduction.hpp"
#include "subject.hpp"
#include "synthetic.hpp"
#include "tables.hpp"
#include "walk.hpp"
