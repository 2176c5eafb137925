// libFuzzer target: the text users and dataset authors write. The program's
// configuration (`--config FILE`: every module's section and rules, read as
// the program reads it) and dataset.yaml may refuse input only with
// core::FileError. What they accept must hold: an accepted configuration
// meets every rule and its dump reads back to the same dump; an accepted
// dataset.yaml written out again reads back to the same text.
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <string_view>

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

void readConfig(std::string_view text) {
  dcl::apps::AppConfig config;
  try {
    dcl::io::applyYaml(text, config, "config.yaml");
  } catch (const dcl::core::FileError&) {
    return;
  }
  if (const auto violation = dcl::core::firstViolation(config))
    broken("an accepted configuration breaks a rule", dcl::core::describe(*violation));
  // The fields alone: what reads back is the same, in a third of the text.
  const std::string dump = dcl::io::dumpConfig(config, /*comments=*/false);
  dcl::apps::AppConfig again;
  try {
    dcl::io::applyYaml(dump, again, "dump.yaml");
  } catch (const dcl::core::FileError& e) {
    broken("the dump of an accepted configuration is refused", e.what());
  }
  if (dcl::io::dumpConfig(again, /*comments=*/false) != dump)
    broken("the dump does not read back", dump);
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
