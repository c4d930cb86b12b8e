#include "optinav/util/error.h"

#include <cstdio>
#include <cstdlib>

namespace optinav {

std::string FormatErrorMessage(const std::string& message, const ErrorContext& context) {
  std::string out;
  if (!context.file.empty()) {
    out += context.file;
    if (context.line > 0) out += ":" + std::to_string(context.line);
    out += ": ";
  } else if (context.line > 0) {
    out += "line " + std::to_string(context.line) + ": ";
  }
  if (!context.field.empty()) out += "field '" + context.field + "': ";
  out += message;
  return out;
}

Error::Error(const std::string& message, ErrorContext context)
    : std::runtime_error(FormatErrorMessage(message, context)),
      context_(std::move(context)),
      message_(message) {}

namespace internal {
void CheckFailed(const char* expr, const char* file, int line, const std::string& msg) {
  std::fprintf(stderr, "optinav internal check failed: %s at %s:%d%s%s\n", expr, file, line,
               msg.empty() ? "" : ": ", msg.c_str());
  std::abort();
}
}  // namespace internal

}  // namespace optinav
