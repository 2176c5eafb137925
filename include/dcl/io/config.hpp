#pragma once

/// YAML configuration for every module, through one convention.
///
/// Each module's config is a plain struct with a commented default on every
/// field and a member
///
///     template <class Visitor>
///     void visit(Visitor& v) {
///       v.field("voxel_size", voxel_size, "voxel edge of the local map, metres");
///       v.section("keyframes", keyframes);  // a nested config struct
///     }
///
/// loadConfig / applyYaml start from the struct's current values (its defaults)
/// and override only the keys the YAML names; dumpConfig prints the effective
/// configuration, doc strings as comments, in YAML that loads back to the same
/// values. yaml-cpp stays behind ConfigVisitor: this header does not include it.
///
/// Supported field types: bool, int, std::int64_t, std::uint32_t, std::uint64_t,
/// float, double, std::string, std::vector<double>, std::vector<std::string> and
/// fixed-size Eigen column vectors of double (Eigen::Vector3d, ...).
///
/// What loading rejects, as core::FileError naming the source, the line and the
/// dotted key (`odometry.voxel_size`): malformed YAML; an empty document (a
/// config file that sets nothing is a mistake -- write `{}` to mean "defaults");
/// a key no field or section claims (the message lists the known keys), or a key
/// given twice; a value of the wrong type: a quoted string, sequence or mapping
/// where a number or bool is expected, `1.5` or an out-of-range value for an
/// integer, a negative value for an unsigned field, NaN anywhere, a sequence of
/// the wrong length for an Eigen vector, or no value (`key:`) for a field. A
/// section given as `name:` with nothing under it is an empty section.
/// Numbers are plain YAML scalars (`1e-3`, `.inf`, `-.inf`); booleans are
/// true/false (also True, TRUE, False, FALSE).

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace dcl::io {

/// What a config struct's `visit` talks to: one overload per supported field
/// type, plus nested sections. Readers and writers of configuration derive from
/// it; it can also drive other front ends (command-line overrides, JSON).
class ConfigVisitor {
 public:
  virtual ~ConfigVisitor() = default;

  /// Visits a bool field called `name`; `doc` says what it means (and its unit).
  void field(std::string_view name, bool& value, std::string_view doc) {
    onField(name, value, doc);
  }
  /// Visits an int field.
  void field(std::string_view name, int& value, std::string_view doc) { onField(name, value, doc); }
  /// Visits a 64-bit signed integer field.
  void field(std::string_view name, std::int64_t& value, std::string_view doc) {
    onField(name, value, doc);
  }
  /// Visits a 32-bit unsigned integer field (negative values are rejected).
  void field(std::string_view name, std::uint32_t& value, std::string_view doc) {
    onField(name, value, doc);
  }
  /// Visits a 64-bit unsigned integer field (also std::size_t).
  void field(std::string_view name, std::uint64_t& value, std::string_view doc) {
    onField(name, value, doc);
  }
  /// Visits a float field.
  void field(std::string_view name, float& value, std::string_view doc) {
    onField(name, value, doc);
  }
  /// Visits a double field.
  void field(std::string_view name, double& value, std::string_view doc) {
    onField(name, value, doc);
  }
  /// Visits a string field.
  void field(std::string_view name, std::string& value, std::string_view doc) {
    onField(name, value, doc);
  }
  /// Visits a list of numbers.
  void field(std::string_view name, std::vector<double>& value, std::string_view doc) {
    onField(name, value, doc);
  }
  /// Visits a list of strings.
  void field(std::string_view name, std::vector<std::string>& value, std::string_view doc) {
    onField(name, value, doc);
  }
  /// Visits a fixed-size Eigen vector of doubles, as a sequence of exactly N numbers.
  template <int N>
  void field(std::string_view name, Eigen::Matrix<double, N, 1>& value, std::string_view doc) {
    onFixedVector(name, std::span<double>(value.data(), static_cast<std::size_t>(N)), doc);
  }

  /// Visits a nested config struct (anything with `visit(Visitor&)`) under `name`.
  template <class Config>
  void section(std::string_view name, Config& config, std::string_view doc = {}) {
    if (!enterSection(name, doc)) return;
    config.visit(*this);
    leaveSection();
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
};

/// Overrides fields from a YAML document (see the file comment for what it rejects).
class YamlConfigReader final : public ConfigVisitor {
 public:
  /// Parses `yaml_text`; `source_name` (a path, or e.g. "--config-yaml") names it in
  /// errors. Throws core::FileError on malformed YAML or an empty document.
  YamlConfigReader(std::string_view yaml_text, std::string source_name);
  ~YamlConfigReader() override;
  YamlConfigReader(const YamlConfigReader&) = delete;
  YamlConfigReader& operator=(const YamlConfigReader&) = delete;

  /// After the visit: throws core::FileError for top-level keys no field claimed.
  void finish();

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

 private:
  struct State;
  std::unique_ptr<State> state_;
};

/// Prints the visited fields as commented YAML.
class YamlConfigWriter final : public ConfigVisitor {
 public:
  /// A writer with nothing written yet.
  YamlConfigWriter();
  ~YamlConfigWriter() override;
  YamlConfigWriter(const YamlConfigWriter&) = delete;
  YamlConfigWriter& operator=(const YamlConfigWriter&) = delete;

  /// The YAML text written so far.
  [[nodiscard]] std::string text() const;

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

 private:
  struct State;
  std::unique_ptr<State> state_;
};

/// The text of the config file `path`; throws core::FileError if it cannot be read.
std::string readConfigText(const std::string& path);

/// Overrides the fields of `config` named in `yaml_text`. All or nothing: on an
/// error (core::FileError naming `source_name`, line and key) `config` is unchanged.
template <class Config>
void applyYaml(std::string_view yaml_text, Config& config, const std::string& source_name) {
  Config updated = config;
  YamlConfigReader reader(yaml_text, source_name);
  updated.visit(static_cast<ConfigVisitor&>(reader));
  reader.finish();
  config = std::move(updated);
}

/// Overrides the fields of `config` named in the YAML file `path` (see applyYaml).
template <class Config>
void loadConfig(const std::string& path, Config& config) {
  applyYaml(readConfigText(path), config, path);
}

/// The effective configuration as YAML, each field preceded by its doc string as a
/// comment; loading it back gives the same values.
template <class Config>
std::string dumpConfig(const Config& config) {
  Config copy = config;
  YamlConfigWriter writer;
  copy.visit(static_cast<ConfigVisitor&>(writer));
  return writer.text();
}

}  // namespace dcl::io
