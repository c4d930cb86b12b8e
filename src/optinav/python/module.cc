// The `optinav` Python module: optinav.eval, optinav.maploc and optinav.io over the same app
// and io code as the command line, so a result from Python is the CLI's JSON as a dict.
//
// Errors: optinav::Error (bad input files, I/O, a failed run: exit code 1 of the CLI) becomes
// optinav.Error, a RuntimeError with the CLI's message and the attributes file, line, field
// (None when not known) and message (without the location). Invalid option values (exit code 2
// of the CLI) become ValueError with the CLI's message; wrong argument types TypeError.
#include <cmath>
#include <exception>

#include <pybind11/pybind11.h>

#include "optinav/python/convert.h"
#include "optinav/util/error.h"
#include "optinav/util/logging.h"

namespace optinav::python {

py::str ToStr(const std::string& text) {
  PyObject* s =
      PyUnicode_DecodeUTF8(text.data(), static_cast<Py_ssize_t>(text.size()), "surrogateescape");
  if (s == nullptr) throw py::error_already_set();
  return py::reinterpret_steal<py::str>(s);
}

bool IsPath(const py::handle& value) {
  const py::module_ os = py::module_::import("os");
  return py::isinstance<py::str>(value) || py::isinstance<py::bytes>(value) ||
         py::isinstance(value, os.attr("PathLike"));
}

std::string ToPath(const py::handle& path) {
  return py::module_::import("os").attr("fsencode")(path).cast<std::string>();
}

py::object JsonToPython(const nlohmann::json& j) {
  using Type = nlohmann::json::value_t;
  switch (j.type()) {
    case Type::boolean:
      return py::bool_(j.get<bool>());
    case Type::number_integer:
      return py::int_(j.get<int64_t>());
    case Type::number_unsigned:
      return py::int_(j.get<uint64_t>());
    case Type::number_float: {
      const double v = j.get<double>();
      return std::isfinite(v) ? py::object(py::float_(v)) : py::object(py::none());
    }
    case Type::string:
      return ToStr(j.get_ref<const std::string&>());
    case Type::array: {
      py::list list;
      for (const nlohmann::json& e : j) list.append(JsonToPython(e));
      return list;
    }
    case Type::object: {
      py::dict dict;
      for (const auto& [key, value] : j.items()) dict[ToStr(key)] = JsonToPython(value);
      return dict;
    }
    default:  // null, binary, discarded
      return py::none();
  }
}

void RaiseIfInvalid(const std::string& message) {
  if (!message.empty()) throw py::value_error(message);
}

namespace {

py::object OrNone(const std::string& s) { return s.empty() ? py::object(py::none()) : ToStr(s); }

}  // namespace

}  // namespace optinav::python

PYBIND11_MODULE(optinav, m) {
  namespace py = pybind11;
  using namespace optinav::python;
  m.doc() =
      "optinav from Python: trajectory evaluation (optinav.eval), map localization "
      "(optinav.maploc) and dataset reading (optinav.io). Results are the dicts of the command "
      "line's --json output.";
  m.attr("__version__") = OPTINAV_VERSION;
  optinav::InitLogging();

  // Kept for the process's lifetime: the translator below raises it.
  static py::handle error_type =
      PyErr_NewExceptionWithDoc("optinav.Error",
                                "Bad input or a failed run (the CLI's exit code 1). str(e) is the "
                                "CLI's message; file, line and field say where (None when not "
                                "known), message is the text without the location.",
                                PyExc_RuntimeError, nullptr);
  m.attr("Error") = error_type;
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const optinav::Error& e) {
      const optinav::ErrorContext& c = e.context();
      py::object exc = py::reinterpret_borrow<py::object>(error_type)(ToStr(e.what()));
      exc.attr("file") = OrNone(c.file);
      exc.attr("line") = c.line > 0 ? py::object(py::int_(c.line)) : py::object(py::none());
      exc.attr("field") = OrNone(c.field);
      exc.attr("message") = ToStr(e.message());
      PyErr_SetObject(error_type.ptr(), exc.ptr());
    }
  });

  m.def("set_log_level", &optinav::SetLogLevel, py::arg("level"),
        "Log level of the library's messages on stderr: trace|debug|info|warn|error|off "
        "(as --log-level).");

  const py::object modules = py::module_::import("sys").attr("modules");
  py::module_ eval = m.def_submodule("eval", "Trajectory evaluation with evo's definitions.");
  DefineEval(eval);
  py::module_ maploc = m.def_submodule("maploc", "Frame-to-map localization on orthophotos.");
  DefineMaploc(maploc);
  py::module_ io = m.def_submodule("io", "Dataset readers.");
  DefineIo(io);
  // `import optinav.eval` and `from optinav.eval import ape` work as for a package.
  modules["optinav.eval"] = eval;
  modules["optinav.maploc"] = maploc;
  modules["optinav.io"] = io;
}
