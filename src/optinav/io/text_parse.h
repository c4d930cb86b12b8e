// Fast, strict parsing of line-oriented numeric text files. Every failure throws
// optinav::Error naming the file, the 1-based line and the field.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "optinav/util/error.h"

namespace optinav::io {

// Reads a whole file into memory; throws Error if it cannot be opened or read.
std::string ReadFileToString(const std::string& path);

// A read-only view of a whole file, memory-mapped when possible (no copy); throws Error if it
// cannot be opened.
class MappedFile {
 public:
  explicit MappedFile(const std::string& path);
  ~MappedFile();
  MappedFile(const MappedFile&) = delete;
  MappedFile& operator=(const MappedFile&) = delete;
  std::string_view view() const {
    return data_ ? std::string_view(data_, size_) : std::string_view(fallback_);
  }

 private:
  const char* data_ = nullptr;
  size_t size_ = 0;
  std::string fallback_;
};

// Iterates the lines of a text buffer (LF or CRLF), tracking line numbers.
class LineCursor {
 public:
  explicit LineCursor(std::string_view text) : text_(text) {}
  // Next line without its terminator; false at the end.
  bool Next(std::string_view* line);
  int64_t line_number() const { return line_number_; }

 private:
  std::string_view text_;
  size_t pos_ = 0;
  int64_t line_number_ = 0;
};

// Trims spaces and tabs.
std::string_view Trim(std::string_view s);
// True for blank lines and lines whose first non-blank character is '#'.
bool IsCommentOrBlank(std::string_view line);
// Splits on runs of spaces/tabs (delim == ' ') or on a single character (e.g. ','), trimming
// each field. Reuses `fields`.
void SplitFields(std::string_view line, char delim, std::vector<std::string_view>* fields);

// Strict finite double: the whole field must be a number; NaN and infinities are rejected.
double ParseFiniteDouble(std::string_view field, const ErrorContext& ctx);
// Whole-field signed 64-bit integer.
int64_t ParseInt64(std::string_view field, const ErrorContext& ctx);
// Decimal seconds ("1305031102.175304", "1.4037155e+09") to integer nanoseconds, exactly
// (rounded half away from zero at the nanosecond), without going through a double.
int64_t ParseSecondsToNs(std::string_view field, const ErrorContext& ctx);
// Fast path for a line of numbers separated by `delim` (' ' = runs of blanks, else that char
// with optional blanks around it): parses exactly `count` finite doubles into `out`, with
// field 0 optionally parsed as seconds -> ns (`first_as_seconds`) or integer ns
// (`first_as_int_ns`) into *t_ns. Returns false on any irregularity (wrong count, bad token,
// non-finite), leaving the caller to re-parse slowly for a precise error message.
bool ParseNumberLine(std::string_view line, char delim, int count, bool first_as_seconds,
                     bool first_as_int_ns, int64_t* t_ns, double* out, int min_count = -1);

// Integer nanoseconds to seconds text with 9 decimals (exact).
std::string FormatNsAsSeconds(int64_t t_ns);

// Writes `content` to `path` through a temporary file and a rename, so a reader never sees a
// half-written file and an existing file survives a failed write.
void WriteFileAtomically(const std::string& path, const std::string& content);

// Checks, before any work, that `path` can become an output file: it is not a folder, and the
// nearest existing folder on its way can be written to. Throws an Error naming the path and
// `field` (the flag) otherwise, so a long run does not fail only at its last write.
void CheckOutputFile(const std::string& path, const std::string& field);

// What a forced run does with a non-empty output folder: write into it, or empty it first.
enum class OnForce { kWriteInto, kClear };
// Makes `dir` ready for a command's outputs: creates it, or refuses (Error naming `field`) when it
// exists and is not empty unless `force` (a folder holding kInProgressMarker is named as an
// interrupted run). With `force` and a `completion_marker` (the file a complete run writes last),
// the old marker is removed first, so an interrupted forced run never passes for complete.
void PrepareOutputDir(const std::string& dir, bool force, OnForce on_force = OnForce::kWriteInto,
                      const std::string& field = "--out",
                      const std::string& completion_marker = "");

// A folder that a command is still writing (or that a killed run left) holds this file: written
// first, removed after the completion marker. Dataset readers refuse such a folder, so an
// interrupted simulation is never taken for a short, complete sequence.
inline constexpr const char* kInProgressMarker = "optinav_incomplete.txt";
void MarkInProgress(const std::string& dir, const std::string& what);
void ClearInProgress(const std::string& dir);
// Throws an Error naming `dir` when it holds kInProgressMarker.
void CheckNotInProgress(const std::string& dir);

}  // namespace optinav::io
