#pragma once

/// YAML configuration for every module, through the convention of
/// core/config.hpp (a struct's `visit` lists its fields, sections and rules).
///
/// loadConfig / applyYaml start from the struct's current values (its defaults)
/// and override only the keys the YAML names; dumpConfig prints the effective
/// configuration, doc strings and rules as comments, in YAML that loads back to
/// the same values. yaml-cpp stays behind ConfigVisitor: this header does not
/// include it.
///
/// What loading rejects, as core::FileError naming the source, the line and the
/// dotted key (`odometry.voxel_size`): malformed YAML; an empty document (a
/// config file that sets nothing is a mistake -- write `{}` to mean "defaults");
/// a key no field or section claims (the message lists the known keys), or a key
/// given twice; a value of the wrong type: a quoted string, sequence or mapping
/// where a number or bool is expected, `1.5` or an out-of-range value for an
/// integer, a negative value for an unsigned field, NaN anywhere, a sequence of
/// the wrong length for an Eigen vector, or no value (`key:`) for a field; and a
/// value that breaks a rule of its struct (the message says the rule and the
/// value found; a rule broken by a field the file does not set, because of
/// another field it does, is blamed on the line of that other field, or of the
/// section). A section given as `name:` with nothing under it is an empty
/// section. Numbers are plain YAML scalars (`1e-3`, `.inf`, `-.inf`); booleans
/// are true/false (also True, TRUE, False, FALSE).

#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <dcl/core/config.hpp>

namespace dcl::io {

/// The visitor of core/config.hpp, under the name io has always used.
using ConfigVisitor = core::ConfigVisitor;

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
  void onCheck(bool ok, std::string_view name, std::string_view rule,
               std::string_view related) override;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

/// Prints the visited fields as YAML, each after its doc string and rules as comments.
class YamlConfigWriter final : public ConfigVisitor {
 public:
  /// A writer with nothing written yet; `comments` false writes the fields alone.
  explicit YamlConfigWriter(bool comments = true);
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
  void onCheck(bool ok, std::string_view name, std::string_view rule,
               std::string_view related) override;

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

/// The effective configuration as YAML, each field preceded by its doc string and
/// its rules as comments (unless `comments` is false); loading it back gives the
/// same values.
template <class Config>
std::string dumpConfig(const Config& config, bool comments = true) {
  Config copy = config;
  YamlConfigWriter writer(comments);
  copy.visit(static_cast<ConfigVisitor&>(writer));
  return writer.text();
}

}  // namespace dcl::io
