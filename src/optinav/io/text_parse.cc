#include "optinav/io/text_parse.h"

#include <charconv>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <system_error>

namespace optinav::io {

std::string ReadFileToString(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) throw Error("is a directory, not a file", {.file = path});
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (!f) throw Error("cannot open file", {.file = path});
  std::string data;
  if (std::fseek(f, 0, SEEK_END) == 0) {
    const long size = std::ftell(f);
    if (size > 0) data.resize(static_cast<size_t>(size));
    std::fseek(f, 0, SEEK_SET);
  }
  const size_t got = data.empty() ? 0 : std::fread(data.data(), 1, data.size(), f);
  const bool failed = std::ferror(f) != 0;
  std::fclose(f);
  if (failed || got != data.size()) throw Error("read error", {.file = path});
  return data;
}

bool LineCursor::Next(std::string_view* line) {
  if (pos_ >= text_.size()) return false;
  size_t end = text_.find('\n', pos_);
  if (end == std::string_view::npos) end = text_.size();
  size_t stop = end;
  if (stop > pos_ && text_[stop - 1] == '\r') --stop;
  *line = text_.substr(pos_, stop - pos_);
  pos_ = end + 1;
  ++line_number_;
  return true;
}

std::string_view Trim(std::string_view s) {
  size_t b = 0, e = s.size();
  while (b < e && (s[b] == ' ' || s[b] == '\t')) ++b;
  while (e > b && (s[e - 1] == ' ' || s[e - 1] == '\t')) --e;
  return s.substr(b, e - b);
}

bool IsCommentOrBlank(std::string_view line) {
  const std::string_view t = Trim(line);
  return t.empty() || t.front() == '#';
}

void SplitFields(std::string_view line, char delim, std::vector<std::string_view>* fields) {
  fields->clear();
  if (delim == ' ') {
    size_t i = 0;
    while (i < line.size()) {
      while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
      if (i >= line.size()) break;
      size_t j = i;
      while (j < line.size() && line[j] != ' ' && line[j] != '\t') ++j;
      fields->push_back(line.substr(i, j - i));
      i = j;
    }
    return;
  }
  size_t start = 0;
  while (true) {
    const size_t end = line.find(delim, start);
    fields->push_back(Trim(line.substr(start, end == std::string_view::npos ? end : end - start)));
    if (end == std::string_view::npos) break;
    start = end + 1;
  }
}

double ParseFiniteDouble(std::string_view field, const ErrorContext& ctx) {
  double value = 0;
  const char* begin = field.data();
  const char* end = begin + field.size();
  if (begin != end && *begin == '+') ++begin;  // from_chars rejects a leading '+'
  const auto [ptr, ec] = std::from_chars(begin, end, value);
  if (ec == std::errc::result_out_of_range) {
    throw Error("number out of range: '" + std::string(field) + "'", ctx);
  }
  if (ec != std::errc() || ptr != end || field.empty()) {
    throw Error("not a number: '" + std::string(field) + "'", ctx);
  }
  if (!std::isfinite(value)) throw Error("value is not finite: '" + std::string(field) + "'", ctx);
  return value;
}

int64_t ParseInt64(std::string_view field, const ErrorContext& ctx) {
  int64_t value = 0;
  const char* begin = field.data();
  const char* end = begin + field.size();
  if (begin != end && *begin == '+') ++begin;
  const auto [ptr, ec] = std::from_chars(begin, end, value);
  if (ec != std::errc() || ptr != end || field.empty()) {
    throw Error("not an integer: '" + std::string(field) + "'", ctx);
  }
  return value;
}

int64_t ParseSecondsToNs(std::string_view field, const ErrorContext& ctx) {
  auto fail = [&](const char* why) -> int64_t {
    throw Error(std::string(why) + ": '" + std::string(field) + "'", ctx);
  };
  size_t i = 0;
  const size_t n = field.size();
  bool negative = false;
  if (i < n && (field[i] == '+' || field[i] == '-')) negative = field[i++] == '-';
  // Significant digits accumulate into `mantissa`; `exp10` is the power of ten to apply.
  __int128 mantissa = 0;
  int digits = 0, exp10 = 0;
  bool any_digit = false, seen_point = false;
  for (; i < n; ++i) {
    const char c = field[i];
    if (c >= '0' && c <= '9') {
      any_digit = true;
      if (digits < 30) {
        mantissa = mantissa * 10 + (c - '0');
        if (mantissa != 0) ++digits;
        if (seen_point) --exp10;
      } else if (!seen_point) {
        ++exp10;  // drop digits beyond precision, keep magnitude
      }
    } else if (c == '.' && !seen_point) {
      seen_point = true;
    } else {
      break;
    }
  }
  if (!any_digit) return fail("not a timestamp");
  if (i < n && (field[i] == 'e' || field[i] == 'E')) {
    ++i;
    bool exp_negative = false;
    if (i < n && (field[i] == '+' || field[i] == '-')) exp_negative = field[i++] == '-';
    int e = 0;
    bool exp_digit = false;
    for (; i < n && field[i] >= '0' && field[i] <= '9'; ++i) {
      exp_digit = true;
      if (e < 10000) e = e * 10 + (field[i] - '0');
    }
    if (!exp_digit) return fail("not a timestamp");
    exp10 += exp_negative ? -e : e;
  }
  if (i != n) return fail("not a timestamp");
  exp10 += 9;  // seconds -> nanoseconds
  if (mantissa == 0) return 0;
  if (exp10 >= 0) {
    for (int k = 0; k < exp10; ++k) {
      mantissa *= 10;
      if (mantissa > static_cast<__int128>(INT64_MAX)) return fail("timestamp out of range");
    }
  } else {
    __int128 divisor = 1;
    for (int k = 0; k < -exp10; ++k) {
      divisor *= 10;
      if (divisor > mantissa * 10) return 0;  // far below a nanosecond
    }
    mantissa = (mantissa + divisor / 2) / divisor;
  }
  if (mantissa > static_cast<__int128>(INT64_MAX)) return fail("timestamp out of range");
  const int64_t v = static_cast<int64_t>(mantissa);
  return negative ? -v : v;
}

std::string FormatNsAsSeconds(int64_t t_ns) {
  const bool negative = t_ns < 0;
  const uint64_t a = negative ? static_cast<uint64_t>(-(t_ns + 1)) + 1 : static_cast<uint64_t>(t_ns);
  char buf[48];
  std::snprintf(buf, sizeof(buf), "%s%llu.%09llu", negative ? "-" : "",
                static_cast<unsigned long long>(a / 1000000000ULL),
                static_cast<unsigned long long>(a % 1000000000ULL));
  return buf;
}

void WriteFileAtomically(const std::string& path, const std::string& content) {
  const std::filesystem::path target(path);
  if (target.has_parent_path()) {
    std::error_code ec;
    std::filesystem::create_directories(target.parent_path(), ec);
  }
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw Error("cannot open for writing", {.file = tmp});
    out.write(content.data(), static_cast<std::streamsize>(content.size()));
    out.flush();
    if (!out) {
      std::filesystem::remove(tmp);
      throw Error("write failed (disk full?)", {.file = tmp});
    }
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) {
    std::filesystem::remove(tmp);
    throw Error("cannot rename temporary file into place: " + ec.message(), {.file = path});
  }
}

}  // namespace optinav::io
