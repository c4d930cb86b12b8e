#include "optinav/util/logging.h"

#include <spdlog/sinks/stdout_color_sinks.h>

#include "optinav/util/error.h"

namespace optinav {

void InitLogging() {
  static bool initialised = false;
  if (initialised) return;
  initialised = true;
  auto logger = spdlog::stderr_color_mt("optinav");
  logger->set_pattern("[%^%l%$] %v");
  spdlog::set_default_logger(logger);
}

void SetLogLevel(const std::string& level) {
  const auto parsed = spdlog::level::from_str(level);
  if (parsed == spdlog::level::off && level != "off") {
    throw Error("unknown log level '" + level + "' (trace|debug|info|warn|error|off)",
                {.field = "--log-level"});
  }
  spdlog::set_level(parsed);
}

}  // namespace optinav
