#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <limits>
#include <optional>
#include <set>
#include <type_traits>
#include <utility>

#include <yaml-cpp/yaml.h>

#include <dcl/core/error.hpp>
#include <dcl/io/config.hpp>
#include <dcl/io/file.hpp>

namespace dcl::io {
namespace {

using core::FileError;
using core::FileLocation;

/// Where a value sits: the source it came from, its dotted key and the key's place.
struct Where {
  const std::string& source;
  std::string key;
  YAML::Mark key_mark = YAML::Mark::null_mark();
};

[[noreturn]] void fail(const Where& where, const YAML::Mark& mark, const std::string& what) {
  FileLocation location{where.source};
  if (!mark.is_null()) location.line = static_cast<std::size_t>(mark.line) + 1;
  if (!where.key.empty()) location.field = where.key;
  throw FileError(location, what);
}

bool isQuoted(const YAML::Node& node) {
  return node.Tag() == "!";
}

std::string describeNode(const YAML::Node& node) {
  switch (node.Type()) {
    case YAML::NodeType::Scalar:
      return (isQuoted(node) ? "the quoted string '" : "'") + node.Scalar() + "'";
    case YAML::NodeType::Sequence:
      return "a sequence";
    case YAML::NodeType::Map:
      return "a mapping";
    default:
      return "no value";
  }
}

[[noreturn]] void failType(const Where& where, const YAML::Node& node, const std::string& wanted) {
  // A missing value (`key:`) is marked where the next token starts: blame the key's line.
  const YAML::Mark mark = node.IsNull() && !where.key_mark.is_null() ? where.key_mark : node.Mark();
  fail(where, mark, "expected " + wanted + ", found " + describeNode(node));
}

/// The text of a plain (unquoted) scalar, or a type error naming `wanted`.
const std::string& plainScalar(const YAML::Node& node, const Where& where,
                               const std::string& wanted) {
  if (!node.IsScalar() || isQuoted(node)) failType(where, node, wanted);
  return node.Scalar();
}

bool decodeBool(const YAML::Node& node, const Where& where) {
  const std::string& text = plainScalar(node, where, "true or false");
  if (text == "true" || text == "True" || text == "TRUE") return true;
  if (text == "false" || text == "False" || text == "FALSE") return false;
  failType(where, node, "true or false");
}

template <class Int>
Int decodeInteger(const YAML::Node& node, const Where& where) {
  const std::string wanted =
      std::string(std::is_signed_v<Int> ? "an integer" : "a non-negative integer") + " in [" +
      std::to_string(std::numeric_limits<Int>::min()) + ", " +
      std::to_string(std::numeric_limits<Int>::max()) + "]";
  if (auto value = parseNumber<Int>(plainScalar(node, where, wanted))) return *value;
  failType(where, node, wanted);
}

/// YAML's spellings of infinity, or none.
std::optional<double> yamlInfinity(std::string_view text) {
  if (!text.empty() && (text.front() == '+' || text.front() == '-')) {
    const auto magnitude = yamlInfinity(text.substr(1));
    if (magnitude && text.front() == '-') return -*magnitude;
    return magnitude;
  }
  if (text == ".inf" || text == ".Inf" || text == ".INF") {
    return std::numeric_limits<double>::infinity();
  }
  return std::nullopt;
}

template <class Real>
Real decodeReal(const YAML::Node& node, const Where& where) {
  const std::string& text = plainScalar(node, where, "a number");
  if (auto infinity = yamlInfinity(text)) return static_cast<Real>(*infinity);
  const auto value = parseNumber<Real>(text);
  if (!value) failType(where, node, "a number");
  if (std::isnan(*value)) fail(where, node.Mark(), "NaN is not a valid setting");
  return *value;
}

std::string decodeString(const YAML::Node& node, const Where& where) {
  if (!node.IsScalar()) failType(where, node, "a string (write '' for an empty one)");
  return node.Scalar();
}

template <class T>
void decode(const YAML::Node& node, const Where& where, T& out);

template <class Element>
std::vector<Element> decodeList(const YAML::Node& node, const Where& where) {
  if (!node.IsSequence()) failType(where, node, "a sequence ([a, b, ...])");
  std::vector<Element> list(node.size());
  for (std::size_t i = 0; i < list.size(); ++i) {
    const Where item{where.source, where.key + "[" + std::to_string(i) + "]", where.key_mark};
    decode(node[i], item, list[i]);
  }
  return list;
}

template <class T>
void decode(const YAML::Node& node, const Where& where, T& out) {
  if constexpr (std::is_same_v<T, bool>) {
    out = decodeBool(node, where);
  } else if constexpr (std::is_integral_v<T>) {
    out = decodeInteger<T>(node, where);
  } else if constexpr (std::is_floating_point_v<T>) {
    out = decodeReal<T>(node, where);
  } else if constexpr (std::is_same_v<T, std::string>) {
    out = decodeString(node, where);
  } else {
    out = decodeList<typename T::value_type>(node, where);
  }
}

/// One mapping being read: its node, the dotted prefix of its keys, the keys claimed.
struct Frame {
  YAML::Node node;
  std::string prefix;
  std::vector<std::string> known{};
};

std::string joinKeys(const std::vector<std::string>& keys) {
  std::string text;
  for (const auto& key : keys) text += (text.empty() ? "" : ", ") + key;
  return text.empty() ? "none" : text;
}

/// Throws for a key of `frame` that no field claimed, or that appears twice.
void checkKeys(const Frame& frame, const std::string& source) {
  if (!frame.node.IsMap()) return;
  std::set<std::string> seen;
  for (const auto& entry : frame.node) {
    const std::string key = entry.first.IsScalar() ? entry.first.Scalar() : "?";
    const Where where{source, frame.prefix + key};
    if (!seen.insert(key).second) fail(where, entry.first.Mark(), "key given twice");
    if (std::find(frame.known.begin(), frame.known.end(), key) == frame.known.end()) {
      fail(where, entry.first.Mark(), "unknown key (known here: " + joinKeys(frame.known) + ")");
    }
  }
}

YAML::Node parseDocument(std::string_view text, const std::string& source) {
  const Where where{source, ""};
  YAML::Node root;
  try {
    root = YAML::Load(std::string(text));
  } catch (const YAML::Exception& e) {
    fail(where, e.mark, "malformed YAML: " + e.msg);
  }
  if (root.IsNull()) {
    throw FileError(FileLocation{source, 1}, "no settings (empty document; write {} for defaults)");
  }
  if (!root.IsMap()) failType(where, root, "a mapping of settings at the top level");
  return root;
}

// ---- writing --------------------------------------------------------------

std::string formatReal(double value) {
  if (std::isinf(value)) return value > 0 ? ".inf" : "-.inf";
  if (std::isnan(value)) return ".nan";
  std::array<char, 32> buffer{};
  const auto result = std::to_chars(buffer.data(), buffer.data() + buffer.size(), value);
  return {buffer.data(), result.ptr};
}

std::string formatReal(float value) {
  if (!std::isfinite(value)) return formatReal(static_cast<double>(value));
  std::array<char, 32> buffer{};
  const auto result = std::to_chars(buffer.data(), buffer.data() + buffer.size(), value);
  return {buffer.data(), result.ptr};
}

std::string escapeChar(char c) {
  switch (c) {
    case '"':
      return "\\\"";
    case '\\':
      return "\\\\";
    case '\n':
      return "\\n";
    case '\t':
      return "\\t";
    default:
      break;
  }
  const auto byte = static_cast<unsigned char>(c);
  if (byte >= 0x20 && byte != 0x7f) return std::string(1, c);
  constexpr std::string_view kHex = "0123456789ABCDEF";
  return std::string("\\x") + kHex[byte >> 4] + kHex[byte & 0xf];
}

/// A YAML double-quoted scalar: loads back to exactly `text`.
std::string quote(std::string_view text) {
  std::string out = "\"";
  for (const char c : text) out += escapeChar(c);
  return out + "\"";
}

template <class T>
std::string formatValue(const T& value) {
  if constexpr (std::is_same_v<T, bool>) {
    return value ? "true" : "false";
  } else if constexpr (std::is_integral_v<T>) {
    return std::to_string(value);
  } else if constexpr (std::is_floating_point_v<T>) {
    return formatReal(value);
  } else if constexpr (std::is_same_v<T, std::string>) {
    return quote(value);
  } else {
    std::string out = "[";
    for (const auto& item : value) out += (out.size() > 1 ? ", " : "") + formatValue(item);
    return out + "]";
  }
}

}  // namespace

// ---- YamlConfigReader ------------------------------------------------------

struct YamlConfigReader::State {
  std::string source;
  std::vector<Frame> frames{};

  /// A key's value and where the key is.
  struct Claimed {
    YAML::Node value;
    Where where;
  };

  /// The value of `name` in the current mapping (claiming the key); none when absent.
  std::optional<Claimed> claim(std::string_view name) {
    Frame& frame = frames.back();
    frame.known.emplace_back(name);
    if (!frame.node.IsMap()) return std::nullopt;
    // Const iteration: a mutable operator[] would insert the key.
    for (const auto& entry : std::as_const(frame.node)) {
      if (!entry.first.IsScalar() || entry.first.Scalar() != name) continue;
      return Claimed{entry.second,
                     Where{source, frame.prefix + std::string(name), entry.first.Mark()}};
    }
    return std::nullopt;
  }

  template <class T>
  void apply(std::string_view name, T& value) {
    if (const auto claimed = claim(name)) decode(claimed->value, claimed->where, value);
  }
};

YamlConfigReader::YamlConfigReader(std::string_view yaml_text, std::string source_name)
    : state_(std::make_unique<State>()) {
  state_->source = std::move(source_name);
  state_->frames.push_back(Frame{parseDocument(yaml_text, state_->source), ""});
}

YamlConfigReader::~YamlConfigReader() = default;

void YamlConfigReader::finish() {
  checkKeys(state_->frames.front(), state_->source);
}

void YamlConfigReader::onField(std::string_view name, bool& value, std::string_view) {
  state_->apply(name, value);
}
void YamlConfigReader::onField(std::string_view name, int& value, std::string_view) {
  state_->apply(name, value);
}
void YamlConfigReader::onField(std::string_view name, std::int64_t& value, std::string_view) {
  state_->apply(name, value);
}
void YamlConfigReader::onField(std::string_view name, std::uint32_t& value, std::string_view) {
  state_->apply(name, value);
}
void YamlConfigReader::onField(std::string_view name, std::uint64_t& value, std::string_view) {
  state_->apply(name, value);
}
void YamlConfigReader::onField(std::string_view name, float& value, std::string_view) {
  state_->apply(name, value);
}
void YamlConfigReader::onField(std::string_view name, double& value, std::string_view) {
  state_->apply(name, value);
}
void YamlConfigReader::onField(std::string_view name, std::string& value, std::string_view) {
  state_->apply(name, value);
}
void YamlConfigReader::onField(std::string_view name, std::vector<double>& value,
                               std::string_view) {
  state_->apply(name, value);
}
void YamlConfigReader::onField(std::string_view name, std::vector<std::string>& value,
                               std::string_view) {
  state_->apply(name, value);
}

void YamlConfigReader::onFixedVector(std::string_view name, std::span<double> value,
                                     std::string_view) {
  const auto claimed = state_->claim(name);
  if (!claimed) return;
  const auto list = decodeList<double>(claimed->value, claimed->where);
  if (list.size() != value.size()) {
    failType(claimed->where, claimed->value,
             "a sequence of " + std::to_string(value.size()) + " numbers");
  }
  std::copy(list.begin(), list.end(), value.begin());
}

bool YamlConfigReader::enterSection(std::string_view name, std::string_view) {
  const auto claimed = state_->claim(name);
  if (!claimed) return false;
  if (!claimed->value.IsMap() && !claimed->value.IsNull()) {
    failType(claimed->where, claimed->value, "a mapping of settings");
  }
  state_->frames.push_back(Frame{claimed->value, claimed->where.key + "."});
  return true;
}

void YamlConfigReader::leaveSection() {
  checkKeys(state_->frames.back(), state_->source);
  state_->frames.pop_back();
}

// ---- YamlConfigWriter ------------------------------------------------------

struct YamlConfigWriter::State {
  std::string out;
  std::size_t depth = 0;
  bool after_section = false;  ///< a top-level section just ended

  /// A blank line before each top-level section and before what follows one.
  void separate(bool section) {
    if (depth == 0 && !out.empty() && (section || after_section)) out += "\n";
    after_section = false;
  }

  [[nodiscard]] std::string indent() const { return std::string(2 * depth, ' '); }

  void comment(std::string_view doc) {
    while (!doc.empty()) {
      const std::size_t end = std::min(doc.find('\n'), doc.size());
      out += indent() + "# " + std::string(doc.substr(0, end)) + "\n";
      doc.remove_prefix(std::min(end + 1, doc.size()));
    }
  }

  template <class T>
  void write(std::string_view name, const T& value, std::string_view doc) {
    separate(false);
    comment(doc);
    out += indent() + std::string(name) + ": " + formatValue(value) + "\n";
  }
};

YamlConfigWriter::YamlConfigWriter() : state_(std::make_unique<State>()) {}

YamlConfigWriter::~YamlConfigWriter() = default;

std::string YamlConfigWriter::text() const {
  return state_->out.empty() ? "{}\n" : state_->out;
}

void YamlConfigWriter::onField(std::string_view name, bool& value, std::string_view doc) {
  state_->write(name, value, doc);
}
void YamlConfigWriter::onField(std::string_view name, int& value, std::string_view doc) {
  state_->write(name, value, doc);
}
void YamlConfigWriter::onField(std::string_view name, std::int64_t& value, std::string_view doc) {
  state_->write(name, value, doc);
}
void YamlConfigWriter::onField(std::string_view name, std::uint32_t& value, std::string_view doc) {
  state_->write(name, value, doc);
}
void YamlConfigWriter::onField(std::string_view name, std::uint64_t& value, std::string_view doc) {
  state_->write(name, value, doc);
}
void YamlConfigWriter::onField(std::string_view name, float& value, std::string_view doc) {
  state_->write(name, value, doc);
}
void YamlConfigWriter::onField(std::string_view name, double& value, std::string_view doc) {
  state_->write(name, value, doc);
}
void YamlConfigWriter::onField(std::string_view name, std::string& value, std::string_view doc) {
  state_->write(name, value, doc);
}
void YamlConfigWriter::onField(std::string_view name, std::vector<double>& value,
                               std::string_view doc) {
  state_->write(name, value, doc);
}
void YamlConfigWriter::onField(std::string_view name, std::vector<std::string>& value,
                               std::string_view doc) {
  state_->write(name, value, doc);
}

void YamlConfigWriter::onFixedVector(std::string_view name, std::span<double> value,
                                     std::string_view doc) {
  state_->write(name, std::vector<double>(value.begin(), value.end()), doc);
}

bool YamlConfigWriter::enterSection(std::string_view name, std::string_view doc) {
  state_->separate(true);
  state_->comment(doc);
  state_->out += state_->indent() + std::string(name) + ":\n";
  ++state_->depth;
  return true;
}

void YamlConfigWriter::leaveSection() {
  --state_->depth;
  state_->after_section = state_->depth == 0;
}

std::string readConfigText(const std::string& path) {
  const std::vector<char> bytes = readFile(path);
  return {bytes.begin(), bytes.end()};
}

}  // namespace dcl::io
