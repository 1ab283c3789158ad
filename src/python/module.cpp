// The compiled part of the Python module `fabrik` (docs/python.md).
#include <pybind11/pybind11.h>

PYBIND11_MODULE(_fabrik, m) {
  m.doc() = "fabrikd's tracker, model loading and recordings (the compiled part of `fabrik`)";
  m.attr("__version__") = FABRIK_VERSION;
}
