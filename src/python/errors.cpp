// The C++ library's setup errors as Python exceptions carrying the C++ message: a bad config
// or template is a ValueError (fabrik.ConfigError), a bad recording a ValueError
// (fabrik.FormatError), a calibration the data cannot support a RuntimeError
// (fabrik.CalibrationError), a file that could not be written an OSError. Convergence
// outcomes are never exceptions (Pose.status).
#include <filesystem>

#include "bindings.hpp"
#include "calib/calibrate.hpp"
#include "config/config_error.hpp"
#include "io/marker_trial.hpp"
#include "io/output_file.hpp"

namespace fabrik::python {

void require_file(const std::string& path, const std::string& what) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) {
    PyErr_SetObject(PyExc_FileNotFoundError,
                    py::make_tuple(2, what + " not found: " + path, path).ptr());
    throw py::error_already_set();
  }
}

void bind_errors(py::module_& m) {
  static py::exception<ConfigError> config_error(m, "ConfigError", PyExc_ValueError);
  static py::exception<io::FormatError> format_error(m, "FormatError", PyExc_ValueError);
  static py::exception<calib::CalibrationError> calibration_error(m, "CalibrationError",
                                                                  PyExc_RuntimeError);
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const ConfigError& e) {
      config_error(e.what());
    } catch (const io::OutputFileError& e) {  // before FormatError, of which it is one
      // OSError(errno, strerror, filename) is the subclass for the errno, printed as Python's
      // own: "[Errno 2] cannot open ... (No such file or directory): 'x/c.json'". Without an
      // errno the message alone, which starts with the file ("[Errno None]" would say nothing).
      // The file's name decoded as Python's own open() does (a name that is not UTF-8 too).
      py::object filename = py::reinterpret_steal<py::object>(PyUnicode_DecodeFSDefaultAndSize(
          e.path().data(), static_cast<Py_ssize_t>(e.path().size())));
      if (e.error_number() == 0 || !filename) {
        PyErr_Clear();
        py::object message = py::reinterpret_steal<py::object>(PyUnicode_DecodeFSDefault(e.what()));
        if (message) {
          PyErr_SetObject(PyExc_OSError, message.ptr());
        } else {
          PyErr_Clear();
          PyErr_SetString(PyExc_OSError, "an output file could not be written");
        }
      } else {
        py::object args = py::make_tuple(e.error_number(), e.problem(), filename);
        PyErr_SetObject(PyExc_OSError, args.ptr());
      }
    } catch (const io::FormatError& e) {
      format_error(e.what());
    } catch (const calib::CalibrationError& e) {
      calibration_error(e.what());
    }
  });
}

}  // namespace fabrik::python
