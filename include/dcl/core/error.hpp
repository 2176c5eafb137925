#pragma once

#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>

namespace dcl::core {

/// The project's error type: what went wrong, in one line a user can act on.
class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Where in a file a problem was found: a line (text formats) or a byte offset (binary formats).
struct FileLocation {
  std::string path{};
  std::optional<std::size_t> line{};    ///< 1-based line number
  std::optional<std::uint64_t> byte{};  ///< 0-based byte offset
  std::optional<std::string> field{};   ///< field or key name, when one is to blame
};

/// A file could not be read or written as its format says. The message names
/// the file, the line or byte offset, the field when known, and what was wrong.
class FileError : public Error {
 public:
  FileError(FileLocation location, const std::string& what);

  [[nodiscard]] const FileLocation& location() const { return location_; }

 private:
  FileLocation location_;
};

/// Formats "path:line: field 'x': what" (or "path: byte N: ...").
std::string describe(const FileLocation& location, const std::string& what);

}  // namespace dcl::core
