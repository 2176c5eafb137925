#pragma once

/// Building blocks shared by the readers and writers of `dcl::io`: whole-file
/// reads, atomic writes, a line reader and a bounds-checked byte reader, all
/// raising dcl::core::FileError that names the file and the place.

#include <charconv>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <functional>
#include <optional>
#include <ostream>
#include <span>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include <dcl/core/error.hpp>

namespace dcl::io {

/// The whole content of `path`. Throws FileError if it cannot be opened or read.
std::vector<char> readFile(const std::string& path);

/// Writes `path` through `write` into a temporary file beside it, then renames it
/// over `path`: a failure leaves any existing file untouched. Creates parent folders.
/// When `path` is a symbolic link, the file it points to is replaced (the link stays).
void writeFileAtomic(const std::string& path, const std::function<void(std::ostream&)>& write,
                     bool binary = false);

/// A file being written under a unique temporary name beside its final path,
/// moved there by `commit`: readers of the final path see the old file or the
/// whole new one, never a part, and no other file is touched on the way.
class TempFile {
 public:
  /// Creates the folders and an empty temporary file beside `path` (a unique
  /// hidden name, so that no file of the user's is ever overwritten), following
  /// `path` when it is a symbolic link. Throws FileError naming `path`.
  explicit TempFile(const std::string& path);
  /// Removes the temporary file unless it was committed.
  ~TempFile();
  TempFile(const TempFile&) = delete;
  TempFile& operator=(const TempFile&) = delete;

  /// Where to write.
  [[nodiscard]] const std::string& path() const { return tmp_; }

  /// Gives the file the permissions of a new file (or of the one it replaces)
  /// and renames it over the final path. Throws FileError naming the final path.
  void commit();

 private:
  std::string path_;    ///< as the caller named it, for messages
  std::string target_;  ///< the final file, symbolic links followed
  std::string tmp_;
  bool committed_ = false;
};

/// Throws FileError naming `path` when it does not exist or is not a regular file.
void requireFile(const std::string& path);

/// Splits on spaces, tabs and carriage returns; empty tokens are dropped.
std::vector<std::string_view> splitWhitespace(std::string_view line);

/// Parses a whole token as a number; none if the token is not exactly one number.
template <class T>
std::optional<T> parseNumber(std::string_view token) {
  static_assert(std::is_arithmetic_v<T>);
  T value{};
  const char* first = token.data();
  const char* last = token.data() + token.size();
  if (first != last && *first == '+') ++first;  // from_chars rejects a leading '+'
  const auto [ptr, ec] = std::from_chars(first, last, value);
  if (ec != std::errc() || ptr != last) return std::nullopt;
  return value;
}

/// Reads a text file line by line, counting lines for error messages.
class LineReader {
 public:
  /// Opens `path`; throws FileError if it cannot.
  explicit LineReader(std::string path);

  /// Advances to the next line; false at the end of the file.
  bool next();

  [[nodiscard]] std::string_view line() const { return line_; }
  [[nodiscard]] std::size_t lineNumber() const { return line_number_; }
  [[nodiscard]] const std::string& path() const { return path_; }

  /// Throws FileError at the current line.
  [[noreturn]] void fail(const std::string& what,
                         std::optional<std::string> field = std::nullopt) const;

  /// Parses `token` as a T or fails naming `field` and the token.
  template <class T>
  T number(std::string_view token, const char* field) const {
    if (auto v = parseNumber<T>(token)) return *v;
    fail("'" + std::string(token) + "' is not a number", std::string(field));
  }

 private:
  std::string path_;
  std::ifstream stream_;
  std::string line_;
  std::size_t line_number_ = 0;
};

/// Reads little-endian values from a byte buffer; every read is bounds-checked
/// and an overrun throws FileError with the byte offset.
class ByteReader {
 public:
  ByteReader(std::span<const char> data, std::string path);

  template <class T>
  T read(const char* what) {
    static_assert(std::is_trivially_copyable_v<T>);
    T value;
    readInto(&value, sizeof(T), what);
    return value;
  }

  /// Copies `n` bytes to `dst`.
  void readInto(void* dst, std::size_t n, const char* what);

  /// A view of the next `n` bytes, advancing past them.
  std::span<const char> take(std::size_t n, const char* what);

  /// The next line (without its '\n'), for text headers inside binary files.
  std::string_view readLine(const char* what);

  void skip(std::size_t n, const char* what) { take(n, what); }

  [[nodiscard]] std::size_t offset() const { return offset_; }
  [[nodiscard]] std::size_t remaining() const { return data_.size() - offset_; }
  [[nodiscard]] bool atEnd() const { return offset_ == data_.size(); }
  [[nodiscard]] const std::string& path() const { return path_; }

  /// Throws FileError at the current offset.
  [[noreturn]] void fail(const std::string& what) const;

 private:
  std::span<const char> data_;
  std::string path_;
  std::size_t offset_ = 0;
};

/// How far from 1 the norm of a quaternion read from text may be.
inline constexpr double kQuaternionTolerance = 1e-2;

/// The shortest decimal text that reads back to exactly `value`.
std::string exactText(double value);

/// Throws core::FileError at line `line` of `path`, naming `field` when given.
[[noreturn]] void failAtLine(const std::string& path, std::size_t line,
                             std::optional<std::string> field, const std::string& what);

/// Throws core::FileError at byte `byte` of `path`.
[[noreturn]] void failAtByte(const std::string& path, std::uint64_t byte, const std::string& what);

}  // namespace dcl::io
