// Logging goes through spdlog; this header only fixes the project's conventions:
// messages go to stderr (stdout is for results), verbosity set once by the command line.
#pragma once

#include <string>

#include <spdlog/spdlog.h>

namespace optinav {

// Sets the global level from "trace|debug|info|warn|error|off"; throws optinav::Error otherwise.
void SetLogLevel(const std::string& level);

// Installs a stderr logger with a short pattern. Safe to call more than once.
void InitLogging();

}  // namespace optinav
