// A payload encoding of the output (output.encoding).
#pragma once

namespace fabrik {

enum class Encoding { json, msgpack };

}  // namespace fabrik
