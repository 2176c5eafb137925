#include <algorithm>
#include <limits>
#include <map>

#include <fmt/format.h>
#include <lzf.h>

#include <dcl/core/error.hpp>
#include <dcl/io/file.hpp>
#include <dcl/io/pcd.hpp>

#include "point_fields.hpp"

namespace dcl::io {

namespace {

using detail::Channel;
using detail::PointLayout;
using detail::ScalarKind;
using detail::ScalarType;

/// LZF turns at most 3 bytes into 264, so no valid block inflates more than 88 times.
constexpr std::size_t kMaxLzfRatio = 100;

/// Larger COUNTs are taken as corrupt (real descriptors have a few hundred values).
constexpr std::size_t kMaxFieldCount = 1000000;

enum class DataKind { kAscii, kBinary, kBinaryCompressed };

struct PcdField {
  std::string name;
  ScalarType type;
  std::size_t count = 1;
};

struct PcdHeader {
  std::vector<PcdField> fields;
  std::size_t points = 0;
  std::size_t fields_line = 0;
  DataKind data = DataKind::kAscii;
};

/// The values of one header key and the line they came from.
struct HeaderEntry {
  std::vector<std::string> values;
  std::size_t line = 0;
};
using HeaderEntries = std::map<std::string, HeaderEntry, std::less<>>;

bool isKnownKey(std::string_view key) {
  static constexpr std::array<std::string_view, 10> kKeys = {
      "VERSION", "FIELDS", "COLUMNS", "SIZE",      "TYPE",
      "COUNT",   "WIDTH",  "HEIGHT",  "VIEWPOINT", "POINTS"};
  return key == "DATA" || std::find(kKeys.begin(), kKeys.end(), key) != kKeys.end();
}

/// Reads header lines up to and including DATA; `line` ends as the DATA line's number.
HeaderEntries readHeaderEntries(ByteReader& in, std::size_t& line) {
  HeaderEntries entries;
  while (true) {
    if (in.atEnd()) failAtLine(in.path(), line, std::nullopt, "header ends before the DATA line");
    ++line;
    const auto tokens = splitWhitespace(in.readLine("header line"));
    if (tokens.empty() || tokens[0].front() == '#') continue;
    std::string key(tokens[0] == "COLUMNS" ? "FIELDS" : tokens[0]);
    if (!isKnownKey(key)) failAtLine(in.path(), line, key, "unknown PCD header key");
    if (entries.count(key)) failAtLine(in.path(), line, key, "header key repeated");
    HeaderEntry& entry = entries[key];
    entry.line = line;
    for (std::size_t i = 1; i < tokens.size(); ++i) entry.values.emplace_back(tokens[i]);
    if (key == "DATA") return entries;
  }
}

const HeaderEntry& requireEntry(const HeaderEntries& entries, const std::string& key,
                                const std::string& path, std::size_t line) {
  const auto it = entries.find(key);
  if (it == entries.end()) failAtLine(path, line, key, "missing from the header");
  return it->second;
}

std::size_t parseCount(const HeaderEntry& entry, std::size_t i, const std::string& key,
                       const std::string& path) {
  const auto value = parseNumber<std::size_t>(entry.values[i]);
  if (!value)
    failAtLine(path, entry.line, key, fmt::format("'{}' is not a count", entry.values[i]));
  return *value;
}

std::size_t parseSingleCount(const HeaderEntry& entry, const std::string& key,
                             const std::string& path) {
  if (entry.values.size() != 1) failAtLine(path, entry.line, key, "expected one value");
  return parseCount(entry, 0, key, path);
}

ScalarType parseType(const HeaderEntry& type_entry, std::size_t size, std::size_t i,
                     const std::string& path) {
  const std::string& t = type_entry.values[i];
  ScalarType type{ScalarKind::kFloat, size};
  if (t == "I") type.kind = ScalarKind::kInt;
  if (t == "U") type.kind = ScalarKind::kUint;
  if ((t != "F" && t != "I" && t != "U") || !detail::isValid(type)) {
    failAtLine(path, type_entry.line, "TYPE",
               fmt::format("type '{}' of size {} is not supported", t, size));
  }
  return type;
}

/// One value per field in SIZE, TYPE and COUNT (COUNT may be absent: all 1).
std::vector<PcdField> parseFields(const HeaderEntries& entries, const std::string& path,
                                  std::size_t data_line) {
  const HeaderEntry& names = requireEntry(entries, "FIELDS", path, data_line);
  const HeaderEntry& sizes = requireEntry(entries, "SIZE", path, data_line);
  const HeaderEntry& types = requireEntry(entries, "TYPE", path, data_line);
  const auto counts = entries.find("COUNT");
  const std::size_t n = names.values.size();
  if (n == 0) failAtLine(path, names.line, "FIELDS", "no fields");
  for (const auto* e : {&sizes, &types, counts == entries.end() ? &names : &counts->second}) {
    if (e->values.size() != n) {
      failAtLine(path, e->line, std::nullopt,
                 fmt::format("{} values for {} FIELDS", e->values.size(), n));
    }
  }
  std::vector<PcdField> fields(n);
  for (std::size_t i = 0; i < n; ++i) {
    fields[i].name = names.values[i];
    fields[i].type = parseType(types, parseCount(sizes, i, "SIZE", path), i, path);
    if (counts != entries.end()) fields[i].count = parseCount(counts->second, i, "COUNT", path);
    if (fields[i].count == 0 || fields[i].count > kMaxFieldCount) {
      failAtLine(path, counts->second.line, "COUNT",
                 fmt::format("a COUNT of {} (expected 1 to {})", fields[i].count, kMaxFieldCount));
    }
  }
  return fields;
}

DataKind parseDataKind(const HeaderEntry& entry, const std::string& path) {
  if (entry.values.size() == 1) {
    if (entry.values[0] == "ascii") return DataKind::kAscii;
    if (entry.values[0] == "binary") return DataKind::kBinary;
    if (entry.values[0] == "binary_compressed") return DataKind::kBinaryCompressed;
  }
  failAtLine(path, entry.line, "DATA", "expected ascii, binary or binary_compressed");
}

/// POINTS (or WIDTH * HEIGHT when absent), checked against WIDTH * HEIGHT.
std::size_t parsePoints(const HeaderEntries& entries, const std::string& path,
                        std::size_t data_line) {
  const HeaderEntry& width_entry = requireEntry(entries, "WIDTH", path, data_line);
  const std::size_t width = parseSingleCount(width_entry, "WIDTH", path);
  const auto height_entry = entries.find("HEIGHT");
  const std::size_t height =
      height_entry == entries.end() ? 1 : parseSingleCount(height_entry->second, "HEIGHT", path);
  const auto product = detail::checkedMul(width, height);
  if (!product) failAtLine(path, width_entry.line, "WIDTH", "WIDTH * HEIGHT overflows");
  const auto points_entry = entries.find("POINTS");
  if (points_entry == entries.end()) return *product;
  const std::size_t points = parseSingleCount(points_entry->second, "POINTS", path);
  if (points != *product) {
    failAtLine(path, points_entry->second.line, "POINTS",
               fmt::format("{} differs from WIDTH * HEIGHT = {}", points, *product));
  }
  return points;
}

PcdHeader parsePcdHeader(ByteReader& in, std::size_t& line) {
  const HeaderEntries entries = readHeaderEntries(in, line);
  PcdHeader header;
  header.fields = parseFields(entries, in.path(), line);
  header.fields_line = entries.at("FIELDS").line;
  header.points = parsePoints(entries, in.path(), line);
  header.data = parseDataKind(entries.at("DATA"), in.path());
  return header;
}

std::size_t fieldBytes(const PcdField& f) {
  return f.type.size * f.count;
}

std::size_t recordBytes(const std::vector<PcdField>& fields) {
  std::size_t total = 0;
  for (const auto& f : fields) total += fieldBytes(f);
  return total;
}

/// Where each channel lives. Binary: byte offsets, records one after another
/// (`n` = 0) or fields one after another (`n` points each). ASCII: token indices.
PointLayout makeLayout(const PcdHeader& header, const std::string& path, bool ascii,
                       std::size_t n = 0) {
  PointLayout layout;
  const std::size_t record = recordBytes(header.fields);
  std::size_t offset = 0;
  for (const auto& f : header.fields) {
    const auto channel = detail::channelOf(f.name);
    if (channel && f.count != 1) {
      failAtLine(path, header.fields_line, f.name, "COUNT must be 1 for a point channel");
    }
    if (channel) {
      const std::size_t at = ascii || n == 0 ? offset : offset * n;
      layout.assign(*channel, {at, n == 0 ? record : fieldBytes(f), f.type, f.name});
    }
    offset += ascii ? f.count : fieldBytes(f);
  }
  if (auto missing = layout.missingXyz()) failAtLine(path, header.fields_line, *missing, "missing");
  return layout;
}

core::PointCloud decode(std::span<const char> data, std::size_t n, const PointLayout& layout,
                        const PcdReadOptions& options, const std::string& path,
                        std::size_t data_offset) {
  detail::CloudBuilder builder(layout, options.drop_nan);
  detail::decodeBinaryPoints(data, n, layout, builder, path, data_offset);
  return builder.finish(std::nullopt);
}

core::PointCloud readBinary(ByteReader& in, const PcdHeader& header,
                            const PcdReadOptions& options) {
  const std::size_t record = recordBytes(header.fields);
  const auto need = detail::checkedMul(header.points, record);
  if (!need || *need > in.remaining()) {
    const std::size_t complete = in.remaining() / std::max<std::size_t>(record, 1);
    throw core::FileError(
        {in.path(), std::nullopt, in.offset() + complete * record},
        fmt::format("truncated data: POINTS says {} points of {} bytes, file ends in point {}",
                    header.points, record, complete));
  }
  const std::size_t data_offset = in.offset();
  const auto data = in.take(*need, "point data");
  return decode(data, header.points, makeLayout(header, in.path(), false), options, in.path(),
                data_offset);
}

/// The decompressed block of a binary_compressed file, `expected` bytes long.
std::vector<char> decompress(ByteReader& in, std::size_t expected) {
  const auto compressed = in.read<std::uint32_t>("compressed size");
  const auto raw = in.read<std::uint32_t>("uncompressed size");
  if (raw != expected) {
    throw core::FileError(
        {in.path(), std::nullopt, in.offset() - 4},
        fmt::format("uncompressed size {} differs from POINTS x record size = {}", raw, expected));
  }
  const std::size_t block_offset = in.offset();
  const auto block = in.take(compressed, "compressed data");
  if (raw > kMaxLzfRatio * std::size_t{compressed} + 1024) {
    in.fail(
        fmt::format("uncompressed size {} impossible for {} compressed bytes", raw, compressed));
  }
  std::vector<char> out(raw);
  const unsigned got = raw == 0 ? 0 : lzf_decompress(block.data(), compressed, out.data(), raw);
  if (got != raw) {
    throw core::FileError({in.path(), std::nullopt, block_offset},
                          fmt::format("corrupt LZF data: decompressed {} of {} bytes", got, raw));
  }
  return out;
}

core::PointCloud readCompressed(ByteReader& in, const PcdHeader& header,
                                const PcdReadOptions& options) {
  const std::size_t record = recordBytes(header.fields);
  const auto need = detail::checkedMul(header.points, record);
  if (!need || *need > std::numeric_limits<std::uint32_t>::max()) {
    in.fail("POINTS x record size exceeds the 4 GiB a compressed block can hold");
  }
  const std::size_t data_offset = in.offset();
  const std::vector<char> data = decompress(in, *need);
  return decode(data, header.points, makeLayout(header, in.path(), false, header.points), options,
                in.path(), data_offset);
}

core::PointCloud readAscii(ByteReader& in, const PcdHeader& header, std::size_t line,
                           const PcdReadOptions& options) {
  const PointLayout layout = makeLayout(header, in.path(), true);
  std::size_t tokens_per_point = 0;
  for (const auto& f : header.fields) tokens_per_point += f.count;
  detail::CloudBuilder builder(layout, options.drop_nan);
  detail::readAsciiPoints(in, line, header.points, tokens_per_point, layout, builder);
  return builder.finish(std::nullopt);
}

// ---- writing ----

std::string headerText(const std::vector<detail::OutField>& fields, std::size_t n,
                       const char* data) {
  // Built with append: GCC 12 warns (falsely, -Wrestrict) on chains of `" " + std::string`.
  std::string names, sizes, types, counts;
  for (const auto& f : fields) {
    names.append(" ").append(f.name);
    sizes.append(" ").append(std::to_string(f.type.size));
    types.append(f.channel == Channel::kRing ? " U" : " F");
    counts.append(" 1");
  }
  const std::string count = std::to_string(n);
  std::string out = "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\n";
  out.append("FIELDS").append(names).append("\nSIZE").append(sizes);
  out.append("\nTYPE").append(types).append("\nCOUNT").append(counts);
  out.append("\nWIDTH ").append(count).append("\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0");
  out.append("\nPOINTS ").append(count).append("\nDATA ").append(data).append("\n");
  return out;
}

std::string compress(const std::string& raw, const std::string& path) {
  std::string block(raw.size() + raw.size() / 16 + 64, '\0');
  const unsigned size = raw.empty()
                            ? 0
                            : lzf_compress(raw.data(), static_cast<unsigned>(raw.size()),
                                           block.data(), static_cast<unsigned>(block.size()));
  if (size == 0 && !raw.empty()) throw core::FileError({path}, "LZF compression failed");
  block.resize(size);
  std::string out(8, '\0');
  const std::array<std::uint32_t, 2> sizes = {size, static_cast<std::uint32_t>(raw.size())};
  std::memcpy(out.data(), sizes.data(), 8);
  return out + block;
}

std::string encodeData(const core::PointCloud& cloud, const std::vector<detail::OutField>& fields,
                       PcdEncoding encoding, const std::string& path) {
  switch (encoding) {
    case PcdEncoding::kAscii:
      return detail::encodeAscii(cloud, fields);
    case PcdEncoding::kBinary:
      return detail::encodeBinary(cloud, fields, false);
    case PcdEncoding::kBinaryCompressed:
      break;
  }
  const std::string raw = detail::encodeBinary(cloud, fields, true);
  if (raw.size() > std::numeric_limits<std::uint32_t>::max()) {
    throw core::FileError({path}, "cloud too large for one compressed PCD block");
  }
  return compress(raw, path);
}

const char* dataName(PcdEncoding encoding) {
  switch (encoding) {
    case PcdEncoding::kAscii:
      return "ascii";
    case PcdEncoding::kBinary:
      return "binary";
    case PcdEncoding::kBinaryCompressed:
      break;
  }
  return "binary_compressed";
}

}  // namespace

core::PointCloud readPcd(const std::string& path, const PcdReadOptions& options) {
  return decodePcd(readFile(path), path, options);
}

core::PointCloud decodePcd(std::span<const char> bytes, const std::string& name,
                           const PcdReadOptions& options) {
  if (bytes.empty()) throw core::FileError({name, std::nullopt, 0}, "empty file");
  ByteReader in(bytes, name);
  std::size_t line = 0;
  const PcdHeader header = parsePcdHeader(in, line);
  switch (header.data) {
    case DataKind::kAscii:
      return readAscii(in, header, line, options);
    case DataKind::kBinary:
      return readBinary(in, header, options);
    case DataKind::kBinaryCompressed:
      break;
  }
  return readCompressed(in, header, options);
}

void writePcd(const std::string& path, const core::PointCloud& cloud,
              const PcdWriteOptions& options) {
  detail::requireConsistent(cloud, path);
  const auto fields = detail::outFields(cloud);
  const std::string text = headerText(fields, cloud.size(), dataName(options.encoding)) +
                           encodeData(cloud, fields, options.encoding, path);
  detail::writeBytes(path, text);
}

}  // namespace dcl::io
