#include "optinav/util/string_printf.h"

#include <cmath>
#include <string>

#include <gtest/gtest.h>

namespace optinav {
namespace {

TEST(StringPrintf, FormatsLikePrintfIncludingNanAndLongOutput) {
  EXPECT_EQ(StringPrintf("%4d|%-3s|%.2f", 7, "ab", 1.005), "   7|ab |1.00");
  EXPECT_EQ(StringPrintf("%.3f", std::nan("")), "nan");
  EXPECT_EQ(StringPrintf("%s", ""), "");
  const std::string long_text(5000, 'x');
  EXPECT_EQ(StringPrintf("<%s>", long_text.c_str()), "<" + long_text + ">");
}

}  // namespace
}  // namespace optinav
