// libFuzzer target: the text users and dataset authors write. The program's
// configuration (`--config FILE`: every module's section and rules, read as
// the program reads it) and dataset.yaml may refuse input only with
// core::FileError. What they accept must hold: an accepted configuration
// meets every rule and its dump reads back to the same dump; an accepted
// dataset.yaml written out again reads back to the same text.
#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <string_view>
#include <vector>

#include <dcl/core/config.hpp>
#include <dcl/core/error.hpp>
#include <dcl/io/config.hpp>
#include <dcl/io/dataset.hpp>

#include "app_config.hpp"

namespace {

[[noreturn]] void broken(const char* what, const std::string& detail) {
  std::fprintf(stderr, "fuzz_config: %s\n%s\n", what, detail.c_str());
  std::abort();
}

/// The lines of `dump` that differ from `defaults` (the dump of the same struct
/// with its defaults: the same fields in the same order, one line each), under
/// the headers of their sections; all of `dump` if the two do not line up.
std::string changedLines(const std::string& dump, const std::string& defaults) {
  const auto split = [](const std::string& text) {
    std::vector<std::string_view> lines;
    for (std::size_t at = 0; at < text.size();) {
      const std::size_t end = std::min(text.find('\n', at), text.size());
      lines.push_back(std::string_view(text).substr(at, end - at));
      at = end + 1;
    }
    return lines;
  };
  const auto indent = [](std::string_view line) { return line.find_first_not_of(' '); };
  const std::vector<std::string_view> ours = split(dump), theirs = split(defaults);
  if (ours.size() != theirs.size()) return dump;
  std::string out;
  std::vector<std::string_view> headers;  // the open sections, outermost first
  std::size_t written = 0;                // of them, already in `out`
  for (std::size_t i = 0; i < ours.size(); ++i) {
    const std::string_view line = ours[i];
    if (line.empty()) continue;
    const std::size_t depth = indent(line) / 2;
    if (headers.size() > depth) headers.resize(depth);
    written = std::min(written, headers.size());
    if (line.back() == ':') {  // a section's header
      headers.push_back(line);
      continue;
    }
    if (line == theirs[i]) continue;
    for (; written < headers.size(); ++written) out.append(headers[written]).push_back('\n');
    out.append(line).push_back('\n');
  }
  return out.empty() ? "{}\n" : out;
}

void readConfig(std::string_view text) {
  dcl::apps::AppConfig config;
  try {
    dcl::io::applyYaml(text, config, "config.yaml");
  } catch (const dcl::core::FileError&) {
    return;
  }
  if (const auto violation = dcl::core::firstViolation(config))
    broken("an accepted configuration breaks a rule", dcl::core::describe(*violation));
  // What reads back is the fields alone, and of them only those the input
  // changed: the defaults' own round trip is the same for every input.
  static const std::string defaults =
      dcl::io::dumpConfig(dcl::apps::AppConfig{}, /*comments=*/false);
  const std::string dump = dcl::io::dumpConfig(config, /*comments=*/false);
  const std::string changed = changedLines(dump, defaults);
  dcl::apps::AppConfig again;
  try {
    dcl::io::applyYaml(changed, again, "changed.yaml");
  } catch (const dcl::core::FileError& e) {
    broken("the dump of an accepted configuration is refused",
           std::string(e.what()) + "\n" + changed);
  }
  if (dcl::io::dumpConfig(again, /*comments=*/false) != dump) {
    broken("the dump does not read back", changed);
  }
}

void readDataset(std::string_view text) {
  dcl::io::DatasetSpec spec;
  try {
    spec = dcl::io::parseDataset(text, "dataset/dataset.yaml");
  } catch (const dcl::core::FileError&) {
    return;
  }
  const std::string written = dcl::io::datasetYaml(spec);
  try {
    const dcl::io::DatasetSpec again = dcl::io::parseDataset(written, "dataset/dataset.yaml");
    if (dcl::io::datasetYaml(again) != written) broken("dataset.yaml does not read back", written);
  } catch (const dcl::core::FileError& e) {
    broken("the dataset.yaml written from an accepted one is refused",
           std::string(e.what()) + "\n" + written);
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  readConfig(text);
  readDataset(text);
  return 0;
}
