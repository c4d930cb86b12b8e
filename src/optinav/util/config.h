// YAML configuration helpers: every failure names the file, line and key.
// Accepts OpenCV/EuRoC style files that begin with the "%YAML:1.0" directive.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <yaml-cpp/yaml.h>

#include "optinav/util/error.h"

namespace optinav {

// A parsed YAML document with the path it came from (for error messages).
struct YamlFile {
  std::string path;
  YAML::Node root;
};

// Reads and parses a YAML file; throws Error naming the file (and line on syntax errors).
YamlFile LoadYamlFile(const std::string& path);
// Parses YAML text; `origin` is used in error messages.
YamlFile ParseYamlString(const std::string& text, const std::string& origin);

namespace internal {
ErrorContext YamlContext(const YamlFile& file, const YAML::Node& node, const std::string& key);
}  // namespace internal

// Required scalar under `key` of `node`; throws Error if missing or of the wrong type.
template <typename T>
T YamlGet(const YamlFile& file, const YAML::Node& node, const std::string& key) {
  const YAML::Node value = node[key];
  if (!value) throw Error("missing required key", internal::YamlContext(file, node, key));
  try {
    return value.as<T>();
  } catch (const YAML::Exception& e) {
    throw Error("cannot convert value '" +
                    (value.IsScalar() ? value.Scalar() : std::string("<non-scalar>")) + "'",
                internal::YamlContext(file, value, key));
  }
}

// Optional scalar: `fallback` when the key is absent; throws Error when present but invalid.
template <typename T>
T YamlGetOr(const YamlFile& file, const YAML::Node& node, const std::string& key, T fallback) {
  if (!node[key]) return fallback;
  return YamlGet<T>(file, node, key);
}

// Sequence of numbers under `key` (also accepts OpenCV matrices {rows, cols, data: [...]}).
// expected_size < 0 accepts any length. Rejects NaN and infinities.
std::vector<double> YamlGetNumbers(const YamlFile& file, const YAML::Node& node,
                                   const std::string& key, int expected_size = -1);

}  // namespace optinav
