#include "optinav/util/string_printf.h"

#include <algorithm>
#include <cstdarg>
#include <cstdio>

namespace optinav {

std::string StringPrintf(const char* format, ...) {
  va_list args, copy;
  va_start(args, format);
  va_copy(copy, args);
  const int n = std::vsnprintf(nullptr, 0, format, copy);
  va_end(copy);
  std::string s(static_cast<size_t>(std::max(n, 0)) + 1, '\0');
  std::vsnprintf(s.data(), s.size(), format, args);
  va_end(args);
  s.resize(static_cast<size_t>(std::max(n, 0)));
  return s;
}

}  // namespace optinav
