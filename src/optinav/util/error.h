// Errors and checks. Three channels, kept apart (docs/ARCHITECTURE.md):
//  - bad input or I/O: throw optinav::Error, which names the file, line and field at fault;
//  - user configuration: Options::Check() returns a message naming the field and value;
//  - programmer invariants: OPTINAV_CHECK, which aborts with the location.
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>

namespace optinav {

// Where in the input a problem was found. Every member is optional.
struct ErrorContext {
  std::string file;   // path of the offending file, if any
  int64_t line = 0;   // 1-based line number, 0 when not applicable
  std::string field;  // column, key or option name, if any
};

// An error in the user's input or environment, carrying where it happened.
class Error : public std::runtime_error {
 public:
  Error(const std::string& message, ErrorContext context = {});

  const ErrorContext& context() const { return context_; }
  // The bare message without the location prefix.
  const std::string& message() const { return message_; }

 private:
  ErrorContext context_;
  std::string message_;
};

// Formats "file:line: field 'x': message" from whatever parts are set.
std::string FormatErrorMessage(const std::string& message, const ErrorContext& context);

namespace internal {
[[noreturn]] void CheckFailed(const char* expr, const char* file, int line, const std::string& msg);
}  // namespace internal

}  // namespace optinav

// Programmer invariant: aborts (never throws) with the failed expression and its location.
#define OPTINAV_CHECK(cond)                                                       \
  do {                                                                            \
    if (!(cond)) ::optinav::internal::CheckFailed(#cond, __FILE__, __LINE__, ""); \
  } while (false)
#define OPTINAV_CHECK_MSG(cond, msg)                                                 \
  do {                                                                               \
    if (!(cond)) ::optinav::internal::CheckFailed(#cond, __FILE__, __LINE__, (msg)); \
  } while (false)
