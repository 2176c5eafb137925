#include <dcl/core/error.hpp>

namespace dcl::core {

std::string describe(const FileLocation& location, const std::string& what) {
  std::string s = location.path.empty() ? std::string("<input>") : location.path;
  // Appended piece by piece: GCC 12 warns (falsely) on `":" + std::to_string(...)`.
  if (location.line) s.append(":").append(std::to_string(*location.line));
  if (location.byte) s.append(": byte ").append(std::to_string(*location.byte));
  s += ": ";
  if (location.field) s += "field '" + *location.field + "': ";
  return s + what;
}

FileError::FileError(FileLocation location, const std::string& what)
    : Error(describe(location, what)), location_(std::move(location)) {}

}  // namespace dcl::core
