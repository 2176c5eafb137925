#include <array>
#include <cerrno>
#include <cstdlib>
#include <filesystem>
#include <system_error>

#include <sys/stat.h>
#include <unistd.h>

#include <dcl/io/file.hpp>

namespace dcl::io {

namespace fs = std::filesystem;
using core::FileError;
using core::FileLocation;

std::vector<char> readFile(const std::string& path) {
  requireFile(path);
  std::ifstream in(path, std::ios::binary);
  if (!in) throw FileError({path}, std::string("cannot open: ") + std::strerror(errno));
  std::error_code ec;
  const auto size = fs::file_size(path, ec);
  if (ec) throw FileError({path}, "cannot read size: " + ec.message());
  std::vector<char> data(size);
  if (size > 0 && !in.read(data.data(), static_cast<std::streamsize>(size))) {
    throw FileError({path}, "read failed");
  }
  return data;
}

namespace {

/// `path` with symbolic links at its end followed (a link to a link, ...), so
/// that writing replaces the file a link points to instead of the link.
fs::path followLinks(const std::string& path) {
  fs::path target(path);
  std::error_code ec;
  for (int hops = 0; hops < 40 && fs::is_symlink(fs::symlink_status(target, ec)); ++hops) {
    const fs::path link = fs::read_symlink(target, ec);
    if (ec) break;
    target = link.is_absolute() ? link : target.parent_path() / link;
  }
  return target;
}

/// The process's umask, read without changing it (umask(2) can only set it).
mode_t currentUmask() {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line)) {
    if (line.rfind("Umask:", 0) == 0)
      return static_cast<mode_t>(std::stoul(line.substr(6), nullptr, 8));
  }
  return 022;
}

}  // namespace

TempFile::TempFile(const std::string& path) : path_(path), target_(followLinks(path).string()) {
  const fs::path target(target_);
  std::error_code ec;
  if (fs::is_directory(target, ec)) throw FileError({path_}, "is a folder, not a file");
  // A bare file name is in the working folder: nothing to create (and `ec`
  // still holds is_directory's "no such file" for a new one).
  if (target.has_parent_path()) {
    fs::create_directories(target.parent_path(), ec);
    if (ec) throw FileError({path_}, "cannot create folder: " + ec.message());
  }
  // Appended piece by piece: GCC 12 warns (falsely) on `"." + std::string`.
  const std::string hidden = std::string(".").append(target.filename().string()).append(".XXXXXX");
  std::string name = (target.parent_path() / hidden).string();
  const int fd = mkstemp(name.data());
  if (fd < 0) throw FileError({path_}, std::string("cannot write: ") + std::strerror(errno));
  ::close(fd);
  tmp_ = std::move(name);
}

TempFile::~TempFile() {
  if (committed_) return;
  std::error_code ec;
  fs::remove(tmp_, ec);
}

void TempFile::commit() {
  std::error_code ec;
  const auto existing = fs::status(target_, ec);
  const auto mode = fs::exists(existing) ? existing.permissions()
                                         : static_cast<fs::perms>(0666 & ~currentUmask());
  fs::permissions(tmp_, mode, ec);
  fs::rename(tmp_, target_, ec);
  if (ec) throw FileError({path_}, "cannot replace file: " + ec.message());
  committed_ = true;
}

void writeFileAtomic(const std::string& path, const std::function<void(std::ostream&)>& write,
                     bool binary) {
  TempFile tmp(path);
  {
    std::ofstream out(tmp.path(), binary ? std::ios::binary | std::ios::trunc : std::ios::trunc);
    if (!out) throw FileError({path}, std::string("cannot write: ") + std::strerror(errno));
    write(out);
    out.flush();
    if (!out) throw FileError({path}, "write failed (disk full?)");
  }
  tmp.commit();
}

void requireFile(const std::string& path) {
  std::error_code ec;
  const auto status = fs::status(path, ec);
  if (!fs::exists(status)) throw FileError({path}, "no such file");
  if (!fs::is_regular_file(status)) throw FileError({path}, "not a regular file");
}

std::vector<std::string_view> splitWhitespace(std::string_view line) {
  std::vector<std::string_view> tokens;
  std::size_t i = 0;
  const auto is_space = [](char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n'; };
  while (i < line.size()) {
    while (i < line.size() && is_space(line[i])) ++i;
    const std::size_t start = i;
    while (i < line.size() && !is_space(line[i])) ++i;
    if (i > start) tokens.push_back(line.substr(start, i - start));
  }
  return tokens;
}

LineReader::LineReader(std::string path) : path_(std::move(path)) {
  requireFile(path_);
  stream_.open(path_);
  if (!stream_) throw FileError({path_}, std::string("cannot open: ") + std::strerror(errno));
}

bool LineReader::next() {
  if (!std::getline(stream_, line_)) return false;
  ++line_number_;
  if (!line_.empty() && line_.back() == '\r') line_.pop_back();
  return true;
}

void LineReader::fail(const std::string& what, std::optional<std::string> field) const {
  throw FileError(FileLocation{path_, line_number_, std::nullopt, std::move(field)}, what);
}

ByteReader::ByteReader(std::span<const char> data, std::string path)
    : data_(data), path_(std::move(path)) {}

std::span<const char> ByteReader::take(std::size_t n, const char* what) {
  if (n > remaining()) {
    fail(std::string("truncated: ") + what + " needs " + std::to_string(n) + " bytes, " +
         std::to_string(remaining()) + " left");
  }
  const auto out = data_.subspan(offset_, n);
  offset_ += n;
  return out;
}

void ByteReader::readInto(void* dst, std::size_t n, const char* what) {
  const auto bytes = take(n, what);
  if (n > 0) std::memcpy(dst, bytes.data(), n);
}

std::string_view ByteReader::readLine(const char* what) {
  if (atEnd()) fail(std::string("truncated: expected ") + what);
  const auto rest = data_.subspan(offset_);
  const auto* nl = static_cast<const char*>(std::memchr(rest.data(), '\n', rest.size()));
  const std::size_t len = nl ? static_cast<std::size_t>(nl - rest.data()) : rest.size();
  std::string_view line(rest.data(), len);
  offset_ += nl ? len + 1 : len;
  if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
  return line;
}

void ByteReader::fail(const std::string& what) const {
  failAtByte(path_, offset_, what);
}

std::string exactText(double value) {
  std::array<char, 32> buffer{};
  const auto result = std::to_chars(buffer.data(), buffer.data() + buffer.size(), value);
  return {buffer.data(), result.ptr};
}

void failAtLine(const std::string& path, std::size_t line, std::optional<std::string> field,
                const std::string& what) {
  throw core::FileError({path, line, std::nullopt, std::move(field)}, what);
}

void failAtByte(const std::string& path, std::uint64_t byte, const std::string& what) {
  throw core::FileError({path, std::nullopt, byte, std::nullopt}, what);
}

}  // namespace dcl::io
