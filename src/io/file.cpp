#include <cerrno>
#include <filesystem>
#include <system_error>

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

void writeFileAtomic(const std::string& path, const std::function<void(std::ostream&)>& write,
                     bool binary) {
  const fs::path target(path);
  std::error_code ec;
  if (target.has_parent_path()) fs::create_directories(target.parent_path(), ec);
  if (ec) throw FileError({path}, "cannot create folder: " + ec.message());
  const fs::path tmp = target.string() + ".tmp";
  {
    std::ofstream out(tmp, binary ? std::ios::binary | std::ios::trunc : std::ios::trunc);
    if (!out) throw FileError({path}, std::string("cannot write: ") + std::strerror(errno));
    try {
      write(out);
    } catch (...) {
      out.close();
      fs::remove(tmp, ec);
      throw;
    }
    out.flush();
    if (!out) {
      out.close();
      fs::remove(tmp, ec);
      throw FileError({path}, "write failed (disk full?)");
    }
  }
  fs::rename(tmp, target, ec);
  if (ec) {
    fs::remove(tmp, ec);
    throw FileError({path}, "cannot replace file: " + ec.message());
  }
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
  throw FileError(FileLocation{path_, std::nullopt, offset_, std::nullopt}, what);
}

}  // namespace dcl::io
