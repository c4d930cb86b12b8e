#include "optinav/util/config.h"

#include <cmath>
#include <fstream>
#include <sstream>

namespace optinav {

YamlFile ParseYamlString(const std::string& text, const std::string& origin) {
  std::string body = text;
  // OpenCV FileStorage writes "%YAML:1.0", which is not valid YAML 1.2; drop that line.
  if (body.rfind("%YAML:", 0) == 0) {
    const size_t eol = body.find('\n');
    body = eol == std::string::npos ? std::string() : "#" + body.substr(eol);
  }
  YamlFile out;
  out.path = origin;
  try {
    out.root = YAML::Load(body);
  } catch (const YAML::ParserException& e) {
    throw Error("YAML syntax error: " + e.msg, {.file = origin, .line = e.mark.line + 1});
  }
  if (!out.root || out.root.IsNull()) throw Error("empty YAML document", {.file = origin});
  if (!out.root.IsMap()) throw Error("expected a YAML mapping at the top level", {.file = origin});
  return out;
}

YamlFile LoadYamlFile(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw Error("cannot open file", {.file = path});
  std::stringstream ss;
  ss << in.rdbuf();
  return ParseYamlString(ss.str(), path);
}

namespace internal {
ErrorContext YamlContext(const YamlFile& file, const YAML::Node& node, const std::string& key) {
  ErrorContext ctx{.file = file.path, .field = key};
  const YAML::Mark mark = node.Mark();
  if (mark.line >= 0) ctx.line = mark.line + 1;
  return ctx;
}
}  // namespace internal

std::vector<double> YamlGetNumbers(const YamlFile& file, const YAML::Node& node,
                                   const std::string& key, int expected_size) {
  YAML::Node value = node[key];
  if (!value) throw Error("missing required key", internal::YamlContext(file, node, key));
  if (value.IsMap() && value["data"]) value = value["data"];
  if (!value.IsSequence()) {
    throw Error("expected a sequence of numbers", internal::YamlContext(file, value, key));
  }
  std::vector<double> out;
  out.reserve(value.size());
  for (size_t i = 0; i < value.size(); ++i) {
    double x = 0;
    try {
      x = value[i].as<double>();
    } catch (const YAML::Exception&) {
      throw Error("element " + std::to_string(i) + " is not a number",
                  internal::YamlContext(file, value[i], key));
    }
    if (!std::isfinite(x)) {
      throw Error("element " + std::to_string(i) + " is not finite",
                  internal::YamlContext(file, value[i], key));
    }
    out.push_back(x);
  }
  if (expected_size >= 0 && static_cast<int>(out.size()) != expected_size) {
    throw Error("expected " + std::to_string(expected_size) + " numbers, found " +
                    std::to_string(out.size()),
                internal::YamlContext(file, value, key));
  }
  return out;
}

}  // namespace optinav
