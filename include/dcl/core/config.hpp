#pragma once

/// The configuration convention of every module: a plain struct with a
/// commented default on every field, its rules beside its fields, and a member
///
///     template <class Visitor>
///     void visit(Visitor& v) {
///       v.field("rows", rows, "radial bins").within(1, 1024);
///       v.field("min_range", min_range, "m").nonNegative().lessThan(max_range, "max_range");
///       v.field("kind", kind, "iris | scancontext").oneOf({"iris", "scancontext"});
///       v.section("keyframes", keyframes);  // a nested config struct
///       v.check(a <= b, "a", "must be at most b");  // any other rule, after its fields
///     }
///
/// Every visitor sees the same rules: the YAML reader (io/config.hpp) refuses
/// the first field that breaks one, naming the file, the line, the dotted key,
/// the rule and the value; the writer prints each rule beside its field's
/// comment; checkConfig refuses a struct built in code the same way (each
/// module's validate() is that check). A struct's defaults meet its rules.
///
/// Supported field types: bool, int, std::int64_t, std::uint32_t, std::uint64_t,
/// float, double, std::string, std::vector<double>, std::vector<std::string> and
/// fixed-size Eigen column vectors of double (Eigen::Vector3d, ...).
///
/// A rule on a floating-point field that compares it with numbers also wants
/// it finite: `.inf` reads as a number, and no setting means infinity.

#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <initializer_list>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

namespace dcl::core {

/// A value as a config file writes it: `true`, `42`, `0.25`, `.inf`, `"text"`
/// (YAML double-quoted, loads back to exactly the string), `[1, 2.5]`.
std::string configText(bool value);
std::string configText(std::int64_t value);                  ///< likewise, signed integers
std::string configText(std::uint64_t value);                 ///< likewise, unsigned integers
std::string configText(double value);                        ///< likewise, the shortest exact text
std::string configText(float value);                         ///< likewise
std::string configText(std::string_view value);              ///< likewise, quoted
std::string configText(std::span<const double> value);       ///< likewise, a flow sequence
std::string configText(std::span<const std::string> value);  ///< likewise, quoted items

/// configText of any supported field type.
template <class T>
std::string configTextOf(const T& value) {
  if constexpr (std::is_same_v<T, bool>) {
    return configText(value);
  } else if constexpr (std::is_integral_v<T> && std::is_signed_v<T>) {
    return configText(static_cast<std::int64_t>(value));
  } else if constexpr (std::is_integral_v<T>) {
    return configText(static_cast<std::uint64_t>(value));
  } else if constexpr (std::is_floating_point_v<T>) {
    return configText(value);
  } else if constexpr (std::is_same_v<T, std::string>) {
    return configText(std::string_view(value));
  } else {
    return configText(std::span(value.data(), static_cast<std::size_t>(value.size())));
  }
}

/// Voxel edges (m) a config may set: voxel grids key at most about a million
/// voxels from the origin (10 km at 1 cm), and at 100 m a scan keeps a handful
/// of points.
inline constexpr double kMinVoxelEdge = 0.01;
inline constexpr double kMaxVoxelEdge = 100.0;

/// Which ends of a range belong to it.
enum class Interval {
  closed,     ///< [lo, hi]
  open,       ///< (lo, hi)
  open_low,   ///< (lo, hi]
  open_high,  ///< [lo, hi)
};

class ConfigVisitor;

/// The rules of one field, chained after ConfigVisitor::field: each says what
/// the value must be and tells the visitor whether it is. Comparisons of
/// floating-point values fail for an infinite value too.
template <class T>
class FieldRules {
 public:
  /// Rules on `value`, the field `name` of the visitor's current section.
  FieldRules(ConfigVisitor& visitor, std::string_view name, const T& value)
      : visitor_(visitor), name_(name), value_(value) {}

  FieldRules& atLeast(T min);      ///< value >= min
  FieldRules& atMost(T max);       ///< value <= max
  FieldRules& greaterThan(T min);  ///< value > min
  FieldRules& lessThan(T max);     ///< value < max
  FieldRules& positive();          ///< greater than 0 (integers: at least 1)
  FieldRules& nonNegative();       ///< at least 0
  FieldRules& finite();            ///< not infinite
  /// lo <= value <= hi, or the ends `interval` says.
  FieldRules& within(T lo, T hi, Interval interval = Interval::closed);
  /// 0 (which means `zero_means`, e.g. "off") or lo <= value <= hi.
  FieldRules& zeroOrWithin(T lo, T hi, std::string_view zero_means);
  /// value < other, where `other` is the field `other_name` of the same section.
  FieldRules& lessThan(const T& other, std::string_view other_name);
  /// value > other, where `other` is the field `other_name` of the same section.
  FieldRules& greaterThan(const T& other, std::string_view other_name);
  /// value >= other, where `other` is the field `other_name` of the same section.
  FieldRules& atLeast(const T& other, std::string_view other_name);
  /// value <= other, where `other` is the field `other_name` of the same section.
  FieldRules& atMost(const T& other, std::string_view other_name);
  /// The value is one of `names` (string fields).
  FieldRules& oneOf(std::initializer_list<std::string_view> names);
  /// Any other rule: `ok` says whether the value meets it, `rule` says it ("must be even");
  /// `related` names the field of the same section it depends on, if one.
  FieldRules& rule(bool ok, std::string_view rule, std::string_view related = {});

 private:
  /// Checks "must be `predicate`"; a floating-point value must also be finite.
  FieldRules& require(bool ok, const std::string& predicate, std::string_view related = {});

  ConfigVisitor& visitor_;
  std::string_view name_;
  const T& value_;
};

/// What a config struct's `visit` talks to: one overload per supported field
/// type, nested sections and rules. Readers, writers and checkers of
/// configuration derive from it.
class ConfigVisitor {
 public:
  virtual ~ConfigVisitor() = default;

  /// Visits a bool field called `name`; `doc` says what it means (and its unit).
  FieldRules<bool> field(std::string_view name, bool& value, std::string_view doc) {
    onField(name, value, doc);
    return {*this, name, value};
  }
  /// Visits an int field.
  FieldRules<int> field(std::string_view name, int& value, std::string_view doc) {
    onField(name, value, doc);
    return {*this, name, value};
  }
  /// Visits a 64-bit signed integer field.
  FieldRules<std::int64_t> field(std::string_view name, std::int64_t& value, std::string_view doc) {
    onField(name, value, doc);
    return {*this, name, value};
  }
  /// Visits a 32-bit unsigned integer field (negative values are rejected).
  FieldRules<std::uint32_t> field(std::string_view name, std::uint32_t& value,
                                  std::string_view doc) {
    onField(name, value, doc);
    return {*this, name, value};
  }
  /// Visits a 64-bit unsigned integer field (also std::size_t).
  FieldRules<std::uint64_t> field(std::string_view name, std::uint64_t& value,
                                  std::string_view doc) {
    onField(name, value, doc);
    return {*this, name, value};
  }
  /// Visits a float field.
  FieldRules<float> field(std::string_view name, float& value, std::string_view doc) {
    onField(name, value, doc);
    return {*this, name, value};
  }
  /// Visits a double field.
  FieldRules<double> field(std::string_view name, double& value, std::string_view doc) {
    onField(name, value, doc);
    return {*this, name, value};
  }
  /// Visits a string field.
  FieldRules<std::string> field(std::string_view name, std::string& value, std::string_view doc) {
    onField(name, value, doc);
    return {*this, name, value};
  }
  /// Visits a list of numbers.
  FieldRules<std::vector<double>> field(std::string_view name, std::vector<double>& value,
                                        std::string_view doc) {
    onField(name, value, doc);
    return {*this, name, value};
  }
  /// Visits a list of strings.
  FieldRules<std::vector<std::string>> field(std::string_view name, std::vector<std::string>& value,
                                             std::string_view doc) {
    onField(name, value, doc);
    return {*this, name, value};
  }
  /// Visits a fixed-size Eigen vector of doubles, as a sequence of exactly N numbers.
  template <int N>
  FieldRules<Eigen::Matrix<double, N, 1>> field(std::string_view name,
                                                Eigen::Matrix<double, N, 1>& value,
                                                std::string_view doc) {
    onFixedVector(name, std::span<double>(value.data(), static_cast<std::size_t>(N)), doc);
    return {*this, name, value};
  }

  /// Visits a nested config struct (anything with `visit(Visitor&)`) under `name`.
  template <class Config>
  void section(std::string_view name, Config& config, std::string_view doc = {}) {
    if (!enterSection(name, doc)) return;
    config.visit(*this);
    leaveSection();
  }

  /// A rule on the field `name` of the current section, visited before it:
  /// `ok` says whether its value meets the rule, `rule` says it ("must be at
  /// least 1"). `related` names another field of the section the rule
  /// compares it with, if any.
  void check(bool ok, std::string_view name, std::string_view rule, std::string_view related = {}) {
    onCheck(ok, name, rule, related);
  }

 protected:
  virtual void onField(std::string_view name, bool& value, std::string_view doc) = 0;
  virtual void onField(std::string_view name, int& value, std::string_view doc) = 0;
  virtual void onField(std::string_view name, std::int64_t& value, std::string_view doc) = 0;
  virtual void onField(std::string_view name, std::uint32_t& value, std::string_view doc) = 0;
  virtual void onField(std::string_view name, std::uint64_t& value, std::string_view doc) = 0;
  virtual void onField(std::string_view name, float& value, std::string_view doc) = 0;
  virtual void onField(std::string_view name, double& value, std::string_view doc) = 0;
  virtual void onField(std::string_view name, std::string& value, std::string_view doc) = 0;
  virtual void onField(std::string_view name, std::vector<double>& value, std::string_view doc) = 0;
  virtual void onField(std::string_view name, std::vector<std::string>& value,
                       std::string_view doc) = 0;
  virtual void onFixedVector(std::string_view name, std::span<double> value,
                             std::string_view doc) = 0;
  /// Starts section `name`; false to skip its fields (e.g. absent from the input).
  virtual bool enterSection(std::string_view name, std::string_view doc) = 0;
  /// Ends the section most recently entered.
  virtual void leaveSection() = 0;
  /// A rule (see check()).
  virtual void onCheck(bool ok, std::string_view name, std::string_view rule,
                       std::string_view related) = 0;
};

// ---- FieldRules -------------------------------------------------------------

template <class T>
FieldRules<T>& FieldRules<T>::require(bool ok, const std::string& predicate,
                                      std::string_view related) {
  if constexpr (std::is_floating_point_v<T>) {
    if (!std::isfinite(value_)) {
      visitor_.check(false, name_, "must be finite and " + predicate, related);
      return *this;
    }
  }
  visitor_.check(ok, name_, "must be " + predicate, related);
  return *this;
}

template <class T>
FieldRules<T>& FieldRules<T>::atLeast(T min) {
  return require(value_ >= min, "at least " + configTextOf(min));
}

template <class T>
FieldRules<T>& FieldRules<T>::atMost(T max) {
  return require(value_ <= max, "at most " + configTextOf(max));
}

template <class T>
FieldRules<T>& FieldRules<T>::greaterThan(T min) {
  return require(value_ > min, "greater than " + configTextOf(min));
}

template <class T>
FieldRules<T>& FieldRules<T>::lessThan(T max) {
  return require(value_ < max, "less than " + configTextOf(max));
}

template <class T>
FieldRules<T>& FieldRules<T>::positive() {
  if constexpr (std::is_integral_v<T>) {
    return atLeast(T{1});
  } else {
    return greaterThan(T{0});
  }
}

template <class T>
FieldRules<T>& FieldRules<T>::nonNegative() {
  return atLeast(T{0});
}

template <class T>
FieldRules<T>& FieldRules<T>::finite() {
  visitor_.check(std::isfinite(value_), name_, "must be finite");
  return *this;
}

template <class T>
FieldRules<T>& FieldRules<T>::within(T lo, T hi, Interval interval) {
  const bool open_low = interval == Interval::open || interval == Interval::open_low;
  const bool open_high = interval == Interval::open || interval == Interval::open_high;
  const bool ok =
      (open_low ? value_ > lo : value_ >= lo) && (open_high ? value_ < hi : value_ <= hi);
  return require(ok, std::string("in ") + (open_low ? "(" : "[") + configTextOf(lo) + ", " +
                         configTextOf(hi) + (open_high ? ")" : "]"));
}

template <class T>
FieldRules<T>& FieldRules<T>::zeroOrWithin(T lo, T hi, std::string_view zero_means) {
  return require(value_ == T{0} || (value_ >= lo && value_ <= hi),
                 "0 (" + std::string(zero_means) + ") or in [" + configTextOf(lo) + ", " +
                     configTextOf(hi) + "]");
}

template <class T>
FieldRules<T>& FieldRules<T>::lessThan(const T& other, std::string_view other_name) {
  return require(value_ < other,
                 "less than " + std::string(other_name) + " (" + configTextOf(other) + ")",
                 other_name);
}

template <class T>
FieldRules<T>& FieldRules<T>::greaterThan(const T& other, std::string_view other_name) {
  return require(value_ > other,
                 "greater than " + std::string(other_name) + " (" + configTextOf(other) + ")",
                 other_name);
}

template <class T>
FieldRules<T>& FieldRules<T>::atLeast(const T& other, std::string_view other_name) {
  return require(value_ >= other,
                 "at least " + std::string(other_name) + " (" + configTextOf(other) + ")",
                 other_name);
}

template <class T>
FieldRules<T>& FieldRules<T>::atMost(const T& other, std::string_view other_name) {
  return require(value_ <= other,
                 "at most " + std::string(other_name) + " (" + configTextOf(other) + ")",
                 other_name);
}

template <class T>
FieldRules<T>& FieldRules<T>::oneOf(std::initializer_list<std::string_view> names) {
  bool ok = false;
  std::string list;
  for (const std::string_view name : names) {
    ok = ok || value_ == name;
    list.append(list.empty() ? "" : ", ").append(name);
  }
  visitor_.check(ok, name_, "must be one of " + list);
  return *this;
}

template <class T>
FieldRules<T>& FieldRules<T>::rule(bool ok, std::string_view rule, std::string_view related) {
  visitor_.check(ok, name_, rule, related);
  return *this;
}

// ---- checking a struct built in code ------------------------------------------

/// The first rule a config breaks: the field's dotted key, the rule and the value.
struct ConfigViolation {
  std::string key;    ///< e.g. "ransac.confidence"
  std::string rule;   ///< e.g. "must be in (0, 1)"
  std::string value;  ///< as configText writes it, e.g. "1.5"
};

/// Runs a config's rules without reading anything; remembers the first broken one.
class ConfigChecker final : public ConfigVisitor {
 public:
  ConfigChecker();
  ~ConfigChecker() override;
  ConfigChecker(const ConfigChecker&) = delete;
  ConfigChecker& operator=(const ConfigChecker&) = delete;

  /// The first rule broken so far; none while every rule held.
  [[nodiscard]] const std::optional<ConfigViolation>& violation() const;

 protected:
  void onField(std::string_view name, bool& value, std::string_view doc) override;
  void onField(std::string_view name, int& value, std::string_view doc) override;
  void onField(std::string_view name, std::int64_t& value, std::string_view doc) override;
  void onField(std::string_view name, std::uint32_t& value, std::string_view doc) override;
  void onField(std::string_view name, std::uint64_t& value, std::string_view doc) override;
  void onField(std::string_view name, float& value, std::string_view doc) override;
  void onField(std::string_view name, double& value, std::string_view doc) override;
  void onField(std::string_view name, std::string& value, std::string_view doc) override;
  void onField(std::string_view name, std::vector<double>& value, std::string_view doc) override;
  void onField(std::string_view name, std::vector<std::string>& value,
               std::string_view doc) override;
  void onFixedVector(std::string_view name, std::span<double> value, std::string_view doc) override;
  bool enterSection(std::string_view name, std::string_view doc) override;
  void leaveSection() override;
  void onCheck(bool ok, std::string_view name, std::string_view rule,
               std::string_view related) override;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

/// The first rule `config` breaks, in visiting order; none when it meets them all.
template <class Config>
std::optional<ConfigViolation> firstViolation(const Config& config) {
  Config copy = config;
  ConfigChecker checker;
  copy.visit(static_cast<ConfigVisitor&>(checker));
  return checker.violation();
}

/// "field 'key': rule, found value".
std::string describe(const ConfigViolation& violation);

/// Throws core::Error "`what`: field 'key': rule, found value".
[[noreturn]] void throwViolation(std::string_view what, const ConfigViolation& violation);

/// Throws as throwViolation for the first rule `config` breaks (what: e.g. "dgs config").
template <class Config>
void checkConfig(const Config& config, std::string_view what) {
  if (const auto violation = firstViolation(config)) throwViolation(what, *violation);
}

}  // namespace dcl::core
