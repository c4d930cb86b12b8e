// printf formatting into a std::string, for output whose exact printf layout (including how NaN
// prints) is part of what users and scripts read; new code uses fmt.
#pragma once

#include <string>

namespace optinav {

std::string StringPrintf(const char* format, ...) __attribute__((format(printf, 1, 2)));

}  // namespace optinav
