// The 3D parameters QTM sends in reply to "GetParameters 3D" (doc, "3D XML
// parameters"): <QTM_Parameters_Ver_n.n><The_3D> with AxisUpwards, Labels (a
// count) and one <Label><Name>..</Name>..</Label> per labelled trajectory, in
// the order of the 3D component's markers. No XML library: a small reader of
// elements, text, the five predefined entities, numeric character
// references, comments and the XML declaration, bounded in size and depth.
// It refuses DOCTYPE, CDATA, processing instructions and anything not
// well formed, rather than guessing.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

namespace fabrik::qtm {

struct Parameters3d {
  std::vector<std::string> labels;  // in the order of the 3D component's markers
  std::string axis_upwards;         // "+Z" and so on; empty when absent
};

struct XmlLimits {
  std::size_t max_bytes = 4u << 20;
  std::size_t max_depth = 32;
  std::size_t max_labels = 4096;
  std::size_t max_text_bytes = 4096;  // one label name or value
};

// Reads the labels and AxisUpwards. false with a one-line reason in `error`
// when the XML is not well formed, has no The_3D block, a Label without a
// Name, an empty or repeated name, a Labels count that differs from the
// Label blocks, or exceeds a limit.
bool read_parameters_3d(std::string_view xml, Parameters3d& out, std::string& error,
                        const XmlLimits& limits = {});

// The XML a server sends for these parameters (for the simulator); names are escaped.
std::string write_parameters_3d(const Parameters3d& params, std::string_view protocol_version);

}  // namespace fabrik::qtm
