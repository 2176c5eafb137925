#pragma once

// Helpers shared by the dcl::io tests: scratch folders, byte-level file edits,
// and the message of the core::FileError a reader throws.

#include <filesystem>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <string>

#include <gtest/gtest.h>
#include <unistd.h>

#include <dcl/core/error.hpp>

namespace dcl::io::test {

/// This process's scratch folder (per process: ctest runs tests in parallel).
inline std::filesystem::path scratchRoot() {
  return std::filesystem::path(::testing::TempDir()) / ("dcl_io_" + std::to_string(::getpid()));
}

/// Removes the scratch folder when the test program ends.
class ScratchCleanup : public ::testing::Environment {
 public:
  void TearDown() override {
    std::error_code ec;
    std::filesystem::remove_all(scratchRoot(), ec);
  }
};
inline ::testing::Environment* const kScratchCleanup =
    ::testing::AddGlobalTestEnvironment(new ScratchCleanup);

/// A fresh folder for one test, removed and recreated.
inline std::filesystem::path freshDir(const std::string& name) {
  const auto dir = scratchRoot() / name;
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

/// Writes `bytes` to `path` as they are.
inline void writeBytes(const std::filesystem::path& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

/// The whole content of `path`; throws std::runtime_error naming a file that
/// cannot be opened (the shared data folder missing), rather than reading it
/// as empty.
inline std::string readBytes(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error(path.string() + ": cannot be opened");
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

/// Success when `text` contains `part`.
inline ::testing::AssertionResult contains(const std::string& text, const std::string& part) {
  if (text.find(part) != std::string::npos) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << "'" << text << "' lacks '" << part << "'";
}

/// The message of the core::FileError that `f` throws; a test failure (and "") if
/// it throws nothing or something else.
template <class F>
std::string fileError(F&& f) {
  try {
    f();
  } catch (const core::FileError& e) {
    return e.what();
  } catch (const std::exception& e) {
    ADD_FAILURE() << "expected core::FileError, got: " << e.what();
    return {};
  }
  ADD_FAILURE() << "expected core::FileError, nothing thrown";
  return {};
}

/// A scratch folder named after the running test, removed afterwards.
class TempDir {
 public:
  TempDir() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    path_ = freshDir(std::string(info->test_suite_name()) + "_" + info->name());
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;

  /// The path of `name` inside the folder.
  [[nodiscard]] std::string file(const std::string& name) const { return (path_ / name).string(); }

  /// Writes `content` to `name` and returns its path.
  [[nodiscard]] std::string write(const std::string& name, const std::string& content) const {
    writeBytes(file(name), content);
    return file(name);
  }

 private:
  std::filesystem::path path_;
};

}  // namespace dcl::io::test
