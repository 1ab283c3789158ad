// `fabrik sim qtm|natnet`: a recording served as Qualisys QTM (RT protocol)
// or OptiTrack Motive (NatNet) would stream it live, to try fabrikd's sources
// without the lab's system. The servers themselves are in src/bridges.
#pragma once

#include <string>
#include <vector>

#include "bridges/sim_recording.hpp"
#include "io/marker_trial.hpp"

namespace fabrik::tools {

// The trial in millimetres, NaN where not seen. `file_up` is the file's up
// axis ("+y", "-z", ...); empty: "+y" for TRC (OpenSim's), "+z" otherwise
// (C3D as Vicon and QTM write it).
bridges::SimRecording sim_recording(const io::MarkerTrial& trial, const std::string& file_up);

// What the command line asks the simulated server to do, in recording
// seconds (converted to frame indices at the recording's rate):
//   --pause-at T:S        hold the stream for S s at time T
//   --drop NAME:T0:T1     the server stops seeing NAME from T0 to T1
//   --rename-at T:OLD=NEW the server's label OLD becomes NEW at T
//   --restart-at T:S      the server goes away at T and comes back S s later
// Each throws std::invalid_argument quoting the spec and the expected form.
struct SimScriptArgs {
  std::vector<std::string> pauses, drops, renames, restarts;
};
bridges::SimScript sim_script(const SimScriptArgs& args, const bridges::SimRecording& recording);

}  // namespace fabrik::tools
