// The compiled part of the Python module `fabrik` (docs/python.md).
#include "bindings.hpp"

PYBIND11_MODULE(_fabrik, m) {
  m.doc() = "fabrikd's tracker, model loading and recordings (the compiled part of `fabrik`)";
  m.attr("__version__") = FABRIK_VERSION;
  using namespace fabrik::python;
  bind_errors(m);
  bind_config(m);
  bind_tracker(m);
  bind_recordings(m);
  bind_solve(m);
  bind_bench(m);
}
