// safe_text lives in common/ (config errors use it too); the wire code keeps
// calling it fabrik::wire::safe_text.
#pragma once

#include "common/safe_text.hpp"

namespace fabrik::wire {
using fabrik::FixedText;
using fabrik::safe_lines;
using fabrik::safe_text;
using fabrik::safe_text_pieces;
}  // namespace fabrik::wire
