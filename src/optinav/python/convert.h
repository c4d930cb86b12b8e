// Shared pieces of the Python module (`import optinav`): conversions between the library's
// values and Python objects, and the definitions of the submodules.
#pragma once

#include <string>

#include <nlohmann/json.hpp>
#include <pybind11/pybind11.h>

namespace optinav::python {

namespace py = pybind11;

// Text to a Python str. Paths and names are bytes, not necessarily UTF-8: invalid sequences
// become surrogate escapes, as os.fsdecode does, so the bytes survive a round trip.
py::str ToStr(const std::string& text);

// A str, bytes or os.PathLike argument to the bytes of the path (os.fsencode).
std::string ToPath(const py::handle& path);

// True when `value` is a str, bytes or os.PathLike (a file rather than an array).
bool IsPath(const py::handle& value);

// A JSON value as the Python value json.loads gives for the CLI's output: objects become dicts,
// arrays lists; a non-finite number (printed as null by the CLI) becomes None.
py::object JsonToPython(const nlohmann::json& j);

// Raises ValueError with `message` when it is not empty (an Options::Check() result, which
// names the CLI flag at fault; the keyword arguments carry the same names).
void RaiseIfInvalid(const std::string& message);

void DefineEval(py::module_& m);
void DefineMaploc(py::module_& m);
void DefineIo(py::module_& m);

}  // namespace optinav::python
