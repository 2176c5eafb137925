#include <algorithm>
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

/// A field of a mapping being read: its value as written, and its key's place
/// (null when the document does not set it).
struct Seen {
  std::string name;
  std::string text;
  YAML::Mark key_mark;
};

/// One mapping being read: its node, the dotted prefix of its keys, where its
/// own key is (null at the top), the keys claimed and the fields visited.
struct Frame {
  YAML::Node node;
  std::string prefix;
  YAML::Mark mark = YAML::Mark::null_mark();
  std::vector<std::string> known{};
  std::vector<Seen> seen{};

  /// The field `name` visited last; none for a name not visited.
  [[nodiscard]] const Seen* find(std::string_view name) const {
    for (auto it = seen.rbegin(); it != seen.rend(); ++it) {
      if (it->name == name) return &*it;
    }
    return nullptr;
  }
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
    const auto claimed = claim(name);
    if (claimed) decode(claimed->value, claimed->where, value);
    see(name, core::configTextOf(value), claimed);
  }

  void see(std::string_view name, std::string text, const std::optional<Claimed>& claimed) {
    frames.back().seen.push_back(Seen{std::string(name), std::move(text),
                                      claimed ? claimed->where.key_mark : YAML::Mark::null_mark()});
  }

  /// Throws for a broken rule on field `name` (see onCheck).
  [[noreturn]] void failRule(std::string_view name, std::string_view rule,
                             std::string_view related) const {
    const Frame& frame = frames.back();
    const Seen* field = frame.find(name);
    const Seen* other = related.empty() ? nullptr : frame.find(related);
    std::string what = std::string(rule) + ", found " + (field ? field->text : "?");
    YAML::Mark mark = field ? field->key_mark : YAML::Mark::null_mark();
    if (mark.is_null()) {
      // The default broke the rule only because of another field this document sets.
      const bool other_set = other != nullptr && !other->key_mark.is_null();
      mark = other_set ? other->key_mark : frame.mark;
      what += other_set ? " (the default; " + std::string(related) + " is set on line " +
                              std::to_string(mark.line + 1) + ")"
                        : " (the default; the file does not set it)";
    }
    fail(Where{source, frame.prefix + std::string(name)}, mark, what);
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
  if (claimed) {
    const auto list = decodeList<double>(claimed->value, claimed->where);
    if (list.size() != value.size()) {
      failType(claimed->where, claimed->value,
               "a sequence of " + std::to_string(value.size()) + " numbers");
    }
    std::copy(list.begin(), list.end(), value.begin());
  }
  state_->see(name, core::configText(std::span<const double>(value)), claimed);
}

bool YamlConfigReader::enterSection(std::string_view name, std::string_view) {
  const auto claimed = state_->claim(name);
  if (!claimed) return false;
  if (!claimed->value.IsMap() && !claimed->value.IsNull()) {
    failType(claimed->where, claimed->value, "a mapping of settings");
  }
  state_->frames.push_back(
      Frame{claimed->value, claimed->where.key + ".", claimed->where.key_mark});
  return true;
}

void YamlConfigReader::leaveSection() {
  checkKeys(state_->frames.back(), state_->source);
  state_->frames.pop_back();
}

void YamlConfigReader::onCheck(bool ok, std::string_view name, std::string_view rule,
                               std::string_view related) {
  if (!ok) state_->failRule(name, rule, related);
}

// ---- YamlConfigWriter ------------------------------------------------------

struct YamlConfigWriter::State {
  /// A line of the output to be: a field or a section's header, its comments and rules.
  struct Entry {
    std::size_t depth = 0;
    bool blank_before = false;
    std::string doc{};
    std::string name{};
    std::optional<std::string> value{};  ///< none: a section's header
    std::vector<std::string> rules{};
  };
  std::vector<Entry> entries{};
  std::size_t depth = 0;
  bool after_section = false;  ///< a top-level section just ended
  bool comments = true;        ///< doc strings and rules written above each field

  /// Adds an entry; a blank line before each top-level section and before what follows one.
  void add(std::string_view name, std::optional<std::string> value, std::string_view doc) {
    const bool section = !value;
    const bool blank = depth == 0 && !entries.empty() && (section || after_section);
    after_section = false;
    entries.push_back(Entry{depth, blank, std::string(doc), std::string(name), std::move(value)});
  }

  template <class T>
  void write(std::string_view name, const T& value, std::string_view doc) {
    add(name, core::configTextOf(value), doc);
  }

  /// The entry of field `name` in the current section; none if not written.
  Entry* find(std::string_view name) {
    for (auto it = entries.rbegin(); it != entries.rend() && it->depth >= depth; ++it) {
      if (it->depth == depth && it->value && it->name == name) return &*it;
    }
    return nullptr;
  }

  [[nodiscard]] std::string render() const {
    std::string out;
    for (const Entry& entry : entries) {
      const std::string indent(2 * entry.depth, ' ');
      if (entry.blank_before) out += "\n";
      if (comments) {
        comment(out, indent, entry.doc);
        std::string rules;
        for (const auto& rule : entry.rules) rules.append(rules.empty() ? "" : "; ").append(rule);
        comment(out, indent, rules);
      }
      out += indent + entry.name + ":" + (entry.value ? " " + *entry.value : "") + "\n";
    }
    return out;
  }

  static void comment(std::string& out, const std::string& indent, std::string_view text) {
    while (!text.empty()) {
      const std::size_t end = std::min(text.find('\n'), text.size());
      out += indent + "# " + std::string(text.substr(0, end)) + "\n";
      text.remove_prefix(std::min(end + 1, text.size()));
    }
  }
};

YamlConfigWriter::YamlConfigWriter(bool comments) : state_(std::make_unique<State>()) {
  state_->comments = comments;
}

YamlConfigWriter::~YamlConfigWriter() = default;

std::string YamlConfigWriter::text() const {
  return state_->entries.empty() ? "{}\n" : state_->render();
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
  state_->add(name, core::configText(std::span<const double>(value)), doc);
}

bool YamlConfigWriter::enterSection(std::string_view name, std::string_view doc) {
  state_->add(name, std::nullopt, doc);
  ++state_->depth;
  return true;
}

void YamlConfigWriter::leaveSection() {
  --state_->depth;
  state_->after_section = state_->depth == 0;
}

void YamlConfigWriter::onCheck(bool, std::string_view name, std::string_view rule,
                               std::string_view) {
  State::Entry* entry = state_->find(name);
  if (entry == nullptr) return;
  if (std::find(entry->rules.begin(), entry->rules.end(), rule) == entry->rules.end())
    entry->rules.emplace_back(rule);
}

std::string readConfigText(const std::string& path) {
  const std::vector<char> bytes = readFile(path);
  return {bytes.begin(), bytes.end()};
}

}  // namespace dcl::io
