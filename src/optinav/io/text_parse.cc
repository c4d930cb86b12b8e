#include "optinav/io/text_parse.h"

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <system_error>

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

namespace optinav::io {

MappedFile::MappedFile(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec))
    throw Error("is a directory, not a file", {.file = path});
  const int fd = ::open(path.c_str(), O_RDONLY);
  if (fd < 0) throw Error("cannot open file", {.file = path});
  struct stat st {};
  if (::fstat(fd, &st) != 0) {
    ::close(fd);
    throw Error("cannot stat file", {.file = path});
  }
  size_ = static_cast<size_t>(st.st_size);
  if (size_ > 0 && S_ISREG(st.st_mode)) {
    void* p = ::mmap(nullptr, size_, PROT_READ, MAP_PRIVATE | MAP_POPULATE, fd, 0);
    if (p != MAP_FAILED) {
      data_ = static_cast<const char*>(p);
      ::madvise(p, size_, MADV_SEQUENTIAL);
    }
  }
  ::close(fd);
  if (data_ == nullptr) {  // not mappable (pipe, special file) or empty: read it instead
    fallback_ = ReadFileToString(path);
    size_ = fallback_.size();
  }
}

MappedFile::~MappedFile() {
  if (data_ != nullptr) ::munmap(const_cast<char*>(data_), size_);
}

std::string ReadFileToString(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec))
    throw Error("is a directory, not a file", {.file = path});
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

namespace {

constexpr double kPow10[] = {1e0,  1e1,  1e2,  1e3,  1e4,  1e5,  1e6,  1e7,  1e8,  1e9,  1e10, 1e11,
                             1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};

// Parses a decimal number at [p, end). Clinger's fast path: with at most 15 significant digits
// and a power of ten up to 22 the result of one multiplication or division is correctly
// rounded; anything else goes to std::from_chars. Returns the end of the number or nullptr.
// True when the 8 bytes at p are all ASCII digits.
inline bool IsEightDigits(uint64_t v) {
  return (((v & 0xF0F0F0F0F0F0F0F0ULL) |
           (((v + 0x0606060606060606ULL) & 0xF0F0F0F0F0F0F0F0ULL) >> 4)) == 0x3333333333333333ULL);
}

// Value of 8 ASCII digits (little-endian load), three multiply-shift steps instead of eight
// dependent multiply-adds.
inline uint64_t EightDigitsValue(uint64_t v) {
  v -= 0x3030303030303030ULL;
  v = (v * 10) + (v >> 8);
  v = (((v & 0x000000FF000000FFULL) * 0x000F424000000064ULL) +
       (((v >> 16) & 0x000000FF000000FFULL) * 0x0000271000000001ULL)) >>
      32;
  return v;
}

// Accumulates the decimal digits at p into *m (which may overflow beyond 19 digits: callers
// check the digit count). Returns the first non-digit.
inline const char* ParseDigits(const char* p, const char* end, uint64_t* m) {
  uint64_t acc = *m;
  while (end - p >= 8) {
    uint64_t v;
    std::memcpy(&v, p, 8);
    if (!IsEightDigits(v)) break;
    acc = acc * 100000000ULL + EightDigitsValue(v);
    p += 8;
  }
  while (p < end && static_cast<unsigned>(*p - '0') < 10u)
    acc = acc * 10 + static_cast<unsigned>(*p++ - '0');
  *m = acc;
  return p;
}

const char* FastDouble(const char* p, const char* end, double* out) {
  const char* start = p;
  bool negative = false;
  if (p < end && (*p == '-' || *p == '+')) negative = *p++ == '-';
  uint64_t m = 0;
  const char* digits_begin = p;
  p = ParseDigits(p, end, &m);
  int n_digits = static_cast<int>(p - digits_begin);
  int exp10 = 0;
  if (p < end && *p == '.') {
    const char* frac_begin = ++p;
    p = ParseDigits(p, end, &m);
    exp10 = -static_cast<int>(p - frac_begin);
    n_digits -= exp10;
  }
  if (n_digits == 0) return nullptr;
  // Exact when no overflow (<= 19 digits), m representable (<= 2^53) and 10^-exp10 exact.
  if (n_digits <= 19 && m <= (uint64_t{1} << 53) && exp10 >= -22 &&
      !(p < end && (*p == 'e' || *p == 'E'))) {
    const double v = static_cast<double>(m) / kPow10[-exp10];
    *out = negative ? -v : v;
    return p;
  }
  const char* b = start;
  if (b < end && *b == '+') ++b;
  const auto [ptr, ec] = std::from_chars(b, end, *out);
  if (ec != std::errc() || !std::isfinite(*out)) return nullptr;
  return ptr;
}

inline bool IsBlank(char c) { return c == ' ' || c == '\t'; }

}  // namespace

bool ParseNumberLine(std::string_view line, char delim, int count, bool first_as_seconds,
                     bool first_as_int_ns, int64_t* t_ns, double* out, int min_count) {
  const char* p = line.data();
  const char* end = p + line.size();
  const int needed = min_count < 0 ? count : min_count;
  int k = 0;
  bool after_delim = false;
  while (true) {
    while (p < end && IsBlank(*p)) ++p;
    if (p == end) {
      if (after_delim) return false;  // a trailing empty field
      break;
    }
    if (k == count) return min_count >= 0;  // extra fields: fine only with min_count
    const char* token_end = p;
    if (k == 0 && (first_as_seconds || first_as_int_ns)) {
      while (token_end < end && !IsBlank(*token_end) && *token_end != delim) ++token_end;
      const std::string_view token(p, static_cast<size_t>(token_end - p));
      if (first_as_int_ns) {
        const auto [ptr, ec] = std::from_chars(p, token_end, *t_ns);
        if (ec != std::errc() || ptr != token_end) return false;
      } else {
        // Seconds with at most 9 decimals: integer arithmetic, else the general parser.
        const char* q = p;
        uint64_t whole = 0, frac = 0;
        q = ParseDigits(q, token_end, &whole);
        // Beyond 9223372035 s the ns count overflows int64: the general parser refuses it.
        const bool whole_ok = q - p <= 11 && whole <= 9'223'372'035;
        bool any_digit = q > p;
        int frac_digits = 0;
        if (q < token_end && *q == '.') {
          const char* f0 = ++q;
          q = ParseDigits(q, token_end, &frac);
          frac_digits = static_cast<int>(q - f0);
          any_digit = any_digit || frac_digits > 0;
        }
        any_digit = any_digit && whole_ok && frac_digits <= 9;
        if (any_digit && q == token_end) {
          static constexpr int64_t kScale[] = {1000000000, 100000000, 10000000, 1000000, 100000,
                                               10000,      1000,      100,      10,      1};
          *t_ns = static_cast<int64_t>(whole) * 1'000'000'000 +
                  static_cast<int64_t>(frac) * kScale[frac_digits];
        } else {
          try {
            *t_ns = ParseSecondsToNs(token, {});
          } catch (const Error&) {
            return false;
          }
        }
      }
    } else {
      token_end = FastDouble(p, end, &out[k]);
      if (token_end == nullptr) return false;
    }
    p = token_end;
    ++k;
    while (p < end && IsBlank(*p)) ++p;
    if (delim != ' ') {
      if (p == end) break;
      if (*p != delim) return false;
      ++p;
      after_delim = true;
    } else if (p < end && !IsBlank(p[-1]) && p == token_end) {
      return false;  // garbage glued to a number, e.g. "1.0abc"
    }
  }
  return k >= needed;
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
  const uint64_t a =
      negative ? static_cast<uint64_t>(-(t_ns + 1)) + 1 : static_cast<uint64_t>(t_ns);
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

void CheckOutputFile(const std::string& path, const std::string& field) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (fs::is_directory(path, ec)) {
    throw Error("is a folder; give the output file's name", {.file = path, .field = field});
  }
  fs::path dir = fs::path(path).parent_path();
  if (dir.empty()) dir = ".";
  while (!fs::exists(dir, ec) && dir.has_parent_path() && dir != dir.parent_path()) {
    dir = dir.parent_path();
  }
  if (fs::exists(dir, ec) && !fs::is_directory(dir, ec)) {
    throw Error("cannot write " + path + ": " + dir.string() + " is not a folder",
                {.file = dir.string(), .field = field});
  }
  if (::access(dir.c_str(), W_OK) != 0) {
    throw Error("cannot write " + path + " into this folder: " + std::strerror(errno),
                {.file = dir.string(), .field = field});
  }
}

void PrepareOutputDir(const std::string& dir, bool force, OnForce on_force,
                      const std::string& field, const std::string& completion_marker) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (fs::exists(dir, ec)) {
    if (!fs::is_directory(dir, ec)) {
      throw Error("exists and is not a directory", {.file = dir, .field = field});
    }
    if (!fs::is_empty(dir, ec)) {
      if (!force && fs::exists(fs::path(dir) / kInProgressMarker, ec)) {
        throw Error(std::string("output folder holds an interrupted run (") + kInProgressMarker +
                        " is still there); use --force to replace it",
                    {.file = dir, .field = field});
      }
      if (!force) {
        throw Error(on_force == OnForce::kClear
                        ? "output folder exists and is not empty (use --force to replace its "
                          "contents)"
                        : "output folder exists and is not empty (use --force to write into it)",
                    {.file = dir, .field = field});
      }
      if (on_force == OnForce::kClear) {
        for (const auto& entry : fs::directory_iterator(dir)) fs::remove_all(entry.path());
      } else if (!completion_marker.empty()) {
        // The old run's marker goes first: if this run is interrupted, the folder must not
        // pass for complete with the new files mixed into the old run's.
        fs::remove(fs::path(dir) / completion_marker, ec);
        if (ec)
          throw Error("cannot remove " + completion_marker + ": " + ec.message(), {.file = dir});
      }
    }
  }
  fs::create_directories(dir, ec);
  if (ec) throw Error("cannot create output folder: " + ec.message(), {.file = dir});
}

void MarkInProgress(const std::string& dir, const std::string& what) {
  WriteFileAtomically((std::filesystem::path(dir) / kInProgressMarker).string(),
                      what +
                          " is writing this folder; this file is removed when it is complete. "
                          "If it is still here, the run was interrupted: run it again.\n");
}

void ClearInProgress(const std::string& dir) {
  std::error_code ec;
  std::filesystem::remove(std::filesystem::path(dir) / kInProgressMarker, ec);
  if (ec)
    throw Error("cannot remove " + std::string(kInProgressMarker) + ": " + ec.message(),
                {.file = dir});
}

void CheckNotInProgress(const std::string& dir) {
  std::error_code ec;
  if (std::filesystem::exists(std::filesystem::path(dir) / kInProgressMarker, ec)) {
    throw Error(std::string("an interrupted run's folder (it holds ") + kInProgressMarker +
                    "): run the command that writes it again",
                {.file = dir});
  }
}

}  // namespace optinav::io
