#include <array>
#include <charconv>
#include <cmath>
#include <utility>

#include <dcl/core/config.hpp>
#include <dcl/core/error.hpp>

namespace dcl::core {
namespace {

template <class Real>
std::string shortestText(Real value) {
  if (std::isinf(value)) return value > 0 ? ".inf" : "-.inf";
  if (std::isnan(value)) return ".nan";
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

template <class Item>
std::string sequenceText(std::span<const Item> items) {
  std::string out = "[";
  for (const auto& item : items) out += (out.size() > 1 ? ", " : "") + configTextOf(item);
  return out + "]";
}

}  // namespace

std::string configText(bool value) {
  return value ? "true" : "false";
}

std::string configText(std::int64_t value) {
  return std::to_string(value);
}

std::string configText(std::uint64_t value) {
  return std::to_string(value);
}

std::string configText(double value) {
  return shortestText(value);
}

std::string configText(float value) {
  return shortestText(value);
}

std::string configText(std::string_view value) {
  std::string out = "\"";
  for (const char c : value) out += escapeChar(c);
  return out + "\"";
}

std::string configText(std::span<const double> value) {
  return sequenceText(value);
}

std::string configText(std::span<const std::string> value) {
  return sequenceText(value);
}

// ---- ConfigChecker -------------------------------------------------------------

struct ConfigChecker::State {
  /// A field of the current section: its name and how to write its value.
  struct Field {
    std::string_view name;
    const void* value;
    std::string (*text)(const void*);
  };
  /// A section being checked: the dotted prefix of its keys and its fields so far.
  struct Frame {
    std::string prefix;
    std::vector<Field> fields{};
    std::vector<std::pair<std::string_view, std::string>> texts{};  ///< fixed vectors
  };
  std::vector<Frame> frames{Frame{""}};
  std::optional<ConfigViolation> violation{};

  template <class T>
  void record(std::string_view name, const T& value) {
    frames.back().fields.push_back(
        {name, &value, [](const void* p) { return configTextOf(*static_cast<const T*>(p)); }});
  }

  [[nodiscard]] std::string textOf(std::string_view name) const {
    const Frame& frame = frames.back();
    for (auto it = frame.fields.rbegin(); it != frame.fields.rend(); ++it) {
      if (it->name == name) return it->text(it->value);
    }
    for (const auto& [field, text] : frame.texts) {
      if (field == name) return text;
    }
    return "?";
  }
};

ConfigChecker::ConfigChecker() : state_(std::make_unique<State>()) {}

ConfigChecker::~ConfigChecker() = default;

const std::optional<ConfigViolation>& ConfigChecker::violation() const {
  return state_->violation;
}

void ConfigChecker::onField(std::string_view name, bool& value, std::string_view) {
  state_->record(name, value);
}
void ConfigChecker::onField(std::string_view name, int& value, std::string_view) {
  state_->record(name, value);
}
void ConfigChecker::onField(std::string_view name, std::int64_t& value, std::string_view) {
  state_->record(name, value);
}
void ConfigChecker::onField(std::string_view name, std::uint32_t& value, std::string_view) {
  state_->record(name, value);
}
void ConfigChecker::onField(std::string_view name, std::uint64_t& value, std::string_view) {
  state_->record(name, value);
}
void ConfigChecker::onField(std::string_view name, float& value, std::string_view) {
  state_->record(name, value);
}
void ConfigChecker::onField(std::string_view name, double& value, std::string_view) {
  state_->record(name, value);
}
void ConfigChecker::onField(std::string_view name, std::string& value, std::string_view) {
  state_->record(name, value);
}
void ConfigChecker::onField(std::string_view name, std::vector<double>& value, std::string_view) {
  state_->record(name, value);
}
void ConfigChecker::onField(std::string_view name, std::vector<std::string>& value,
                            std::string_view) {
  state_->record(name, value);
}

void ConfigChecker::onFixedVector(std::string_view name, std::span<double> value,
                                  std::string_view) {
  state_->frames.back().texts.emplace_back(name, configText(std::span<const double>(value)));
}

bool ConfigChecker::enterSection(std::string_view name, std::string_view) {
  state_->frames.push_back(State::Frame{state_->frames.back().prefix + std::string(name) + "."});
  return true;
}

void ConfigChecker::leaveSection() {
  state_->frames.pop_back();
}

void ConfigChecker::onCheck(bool ok, std::string_view name, std::string_view rule,
                            std::string_view) {
  if (ok || state_->violation) return;
  state_->violation = ConfigViolation{state_->frames.back().prefix + std::string(name),
                                      std::string(rule), state_->textOf(name)};
}

std::string describe(const ConfigViolation& violation) {
  return "field '" + violation.key + "': " + violation.rule + ", found " + violation.value;
}

void throwViolation(std::string_view what, const ConfigViolation& violation) {
  throw Error(std::string(what) + ": " + describe(violation));
}

}  // namespace dcl::core
