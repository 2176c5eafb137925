#include <algorithm>
#include <array>
#include <cstring>
#include <iterator>
#include <utility>

#include <fmt/format.h>

#include <dcl/core/error.hpp>
#include <dcl/io/file.hpp>
#include <dcl/io/ply.hpp>

#include "point_fields.hpp"

namespace dcl::io {

namespace {

using detail::PointLayout;
using detail::ScalarKind;
using detail::ScalarType;

enum class PlyFormat { kAscii, kBinaryLittleEndian, kBinaryBigEndian };

struct PlyProperty {
  std::string name;
  ScalarType type;                       // the value type, or a list's item type
  std::optional<ScalarType> list_count;  // the count type of a list property
};

struct PlyElement {
  std::string name;
  std::size_t count = 0;
  std::size_t line = 0;
  std::vector<PlyProperty> properties;
};

struct PlyHeader {
  PlyFormat format = PlyFormat::kAscii;
  std::vector<PlyElement> elements;
};

std::optional<ScalarType> scalarTypeOf(std::string_view name) {
  static constexpr std::array<std::pair<std::string_view, ScalarType>, 16> kTypes = {{
      {"char", {ScalarKind::kInt, 1}},
      {"int8", {ScalarKind::kInt, 1}},
      {"uchar", {ScalarKind::kUint, 1}},
      {"uint8", {ScalarKind::kUint, 1}},
      {"short", {ScalarKind::kInt, 2}},
      {"int16", {ScalarKind::kInt, 2}},
      {"ushort", {ScalarKind::kUint, 2}},
      {"uint16", {ScalarKind::kUint, 2}},
      {"int", {ScalarKind::kInt, 4}},
      {"int32", {ScalarKind::kInt, 4}},
      {"uint", {ScalarKind::kUint, 4}},
      {"uint32", {ScalarKind::kUint, 4}},
      {"float", {ScalarKind::kFloat, 4}},
      {"float32", {ScalarKind::kFloat, 4}},
      {"double", {ScalarKind::kFloat, 8}},
      {"float64", {ScalarKind::kFloat, 8}},
  }};
  for (const auto& [n, type] : kTypes) {
    if (n == name) return type;
  }
  return std::nullopt;
}

ScalarType requireType(std::string_view token, const std::string& path, std::size_t line,
                       const std::string& property) {
  const auto type = scalarTypeOf(token);
  if (!type) failAtLine(path, line, property, fmt::format("unknown property type '{}'", token));
  return *type;
}

PlyProperty parseProperty(const std::vector<std::string_view>& tokens, const std::string& path,
                          std::size_t line) {
  const bool list = tokens.size() > 1 && tokens[1] == "list";
  if (tokens.size() != (list ? 5u : 3u)) {
    failAtLine(path, line, std::nullopt,
               "expected 'property <type> <name>' or 'property list <count type> <type> <name>'");
  }
  PlyProperty p;
  p.name = std::string(tokens.back());
  p.type = requireType(tokens[tokens.size() - 2], path, line, p.name);
  if (list) {
    p.list_count = requireType(tokens[2], path, line, p.name);
    if (p.list_count->kind == ScalarKind::kFloat) {
      failAtLine(path, line, p.name, "a list count must be of an integer type");
    }
  }
  return p;
}

PlyElement parseElement(const std::vector<std::string_view>& tokens, const std::string& path,
                        std::size_t line) {
  if (tokens.size() != 3) failAtLine(path, line, std::nullopt, "expected 'element <name> <count>'");
  const auto count = parseNumber<std::size_t>(tokens[2]);
  if (!count) {
    failAtLine(path, line, std::string(tokens[1]), fmt::format("'{}' is not a count", tokens[2]));
  }
  return {std::string(tokens[1]), *count, line, {}};
}

PlyFormat parseFormat(const std::vector<std::string_view>& tokens, const std::string& path,
                      std::size_t line) {
  if (tokens.size() != 3 || tokens[2] != "1.0") {
    failAtLine(path, line, "format", "expected 'format <encoding> 1.0'");
  }
  if (tokens[1] == "ascii") return PlyFormat::kAscii;
  if (tokens[1] == "binary_little_endian") return PlyFormat::kBinaryLittleEndian;
  if (tokens[1] == "binary_big_endian") return PlyFormat::kBinaryBigEndian;
  failAtLine(path, line, "format", fmt::format("unknown encoding '{}'", tokens[1]));
}

/// Applies one header line; false at end_header.
bool applyHeaderLine(const std::vector<std::string_view>& tokens, PlyHeader& header,
                     bool& has_format, const std::string& path, std::size_t line) {
  const std::string_view key = tokens[0];
  if (key == "end_header") return false;
  if (key == "comment" || key == "obj_info") return true;
  if (key == "format") {
    header.format = parseFormat(tokens, path, line);
    has_format = true;
  } else if (key == "element") {
    header.elements.push_back(parseElement(tokens, path, line));
  } else if (key == "property") {
    if (header.elements.empty())
      failAtLine(path, line, std::nullopt, "property before any element");
    header.elements.back().properties.push_back(parseProperty(tokens, path, line));
  } else {
    failAtLine(path, line, std::nullopt, fmt::format("unknown header keyword '{}'", key));
  }
  return true;
}

PlyHeader parsePlyHeader(ByteReader& in, std::size_t& line) {
  line = 1;
  if (in.readLine("magic") != "ply") failAtLine(in.path(), 1, std::nullopt, "not a PLY file");
  PlyHeader header;
  bool has_format = false;
  while (true) {
    if (in.atEnd()) failAtLine(in.path(), line, std::nullopt, "header ends before end_header");
    ++line;
    const auto tokens = splitWhitespace(in.readLine("header line"));
    if (tokens.empty()) continue;
    if (!applyHeaderLine(tokens, header, has_format, in.path(), line)) break;
  }
  if (!has_format) failAtLine(in.path(), line, "format", "missing from the header");
  return header;
}

const PlyElement& requireVertex(const PlyHeader& header, const std::string& path,
                                std::size_t line) {
  const auto it = std::find_if(header.elements.begin(), header.elements.end(),
                               [](const PlyElement& e) { return e.name == "vertex"; });
  if (it == header.elements.end()) failAtLine(path, line, "vertex", "no vertex element");
  return *it;
}

std::string_view channelName(std::string_view name) {
  constexpr std::string_view kPrefix = "scalar_";  // CloudCompare's scalar fields
  return name.starts_with(kPrefix) ? name.substr(kPrefix.size()) : name;
}

std::size_t recordBytes(const PlyElement& e) {
  std::size_t total = 0;
  for (const auto& p : e.properties) total += p.type.size;
  return total;
}

/// Where each channel lives in a vertex: byte offsets (binary) or token indices (ascii).
PointLayout vertexLayout(const PlyElement& vertex, PlyFormat format, const std::string& path) {
  PointLayout layout;
  layout.swap = format == PlyFormat::kBinaryBigEndian;
  const bool ascii = format == PlyFormat::kAscii;
  const std::size_t record = recordBytes(vertex);
  std::size_t offset = 0;
  for (const auto& p : vertex.properties) {
    if (p.list_count)
      failAtLine(path, vertex.line, p.name, "list properties of vertices unsupported");
    if (const auto channel = detail::channelOf(channelName(p.name))) {
      layout.assign(*channel, {offset, record, p.type, p.name});
    }
    offset += ascii ? 1 : p.type.size;
  }
  if (auto missing = layout.missingXyz())
    failAtLine(path, vertex.line, *missing, "vertex lacks it");
  return layout;
}

core::PointCloud readBinaryVertices(ByteReader& in, const PlyElement& vertex,
                                    const PointLayout& layout, const PlyReadOptions& options) {
  const std::size_t record = recordBytes(vertex);
  const auto need = detail::checkedMul(vertex.count, record);
  if (!need || *need > in.remaining()) {
    const std::size_t complete = in.remaining() / std::max<std::size_t>(record, 1);
    throw core::FileError(
        {in.path(), std::nullopt, in.offset() + complete * record, "vertex"},
        fmt::format("truncated data: {} vertices of {} bytes, file ends in vertex {}", vertex.count,
                    record, complete));
  }
  const std::size_t data_offset = in.offset();
  detail::CloudBuilder builder(layout, options.drop_nan);
  detail::decodeBinaryPoints(in.take(*need, "vertices"), vertex.count, layout, builder, in.path(),
                             data_offset);
  return builder.finish(std::nullopt);
}

/// The length of a list at the reader, as a whole non-negative number.
std::size_t readListLength(ByteReader& in, const PlyProperty& p, bool swap) {
  const std::size_t at = in.offset();
  const double n =
      detail::loadScalar(in.take(p.list_count->size, p.name.c_str()).data(), *p.list_count, swap);
  if (n < 0) {
    throw core::FileError({in.path(), std::nullopt, at, p.name},
                          fmt::format("negative list length {}", n));
  }
  return static_cast<std::size_t>(n);
}

void skipBinaryElement(ByteReader& in, const PlyElement& e, bool swap) {
  const bool has_list = std::any_of(e.properties.begin(), e.properties.end(),
                                    [](const PlyProperty& p) { return p.list_count.has_value(); });
  if (!has_list) {
    const auto need = detail::checkedMul(e.count, recordBytes(e));
    if (!need) in.fail(fmt::format("element '{}' is too large", e.name));
    in.skip(*need, e.name.c_str());
    return;
  }
  for (std::size_t i = 0; i < e.count; ++i) {
    for (const auto& p : e.properties) {
      const std::size_t items = p.list_count ? readListLength(in, p, swap) : 1;
      const auto bytes = detail::checkedMul(items, p.type.size);
      if (!bytes) in.fail(fmt::format("list '{}' is too long", p.name));
      in.skip(*bytes, p.name.c_str());
    }
  }
}

/// Checks one text line of a non-vertex element: every list as long as it says.
void checkAsciiRecord(const std::vector<std::string_view>& tokens, const PlyElement& e,
                      const std::string& path, std::size_t line) {
  std::size_t at = 0;
  for (const auto& p : e.properties) {
    if (at >= tokens.size()) failAtLine(path, line, p.name, "missing value");
    if (!p.list_count) {
      ++at;
      continue;
    }
    const auto n = detail::parseTyped(tokens[at], *p.list_count);
    if (!n || *n < 0 || *n > static_cast<double>(tokens.size())) {
      failAtLine(path, line, p.name, fmt::format("bad list length '{}'", tokens[at]));
    }
    at += 1 + static_cast<std::size_t>(*n);
  }
  if (at != tokens.size()) {
    failAtLine(path, line, e.name, fmt::format("expected {} values, found {}", at, tokens.size()));
  }
}

void skipAsciiElement(ByteReader& in, std::size_t& line, const PlyElement& e) {
  for (std::size_t i = 0; i < e.count;) {
    if (in.atEnd()) {
      failAtLine(in.path(), line, e.name,
                 fmt::format("truncated data: expected {} records, found {}", e.count, i));
    }
    ++line;
    const auto tokens = splitWhitespace(in.readLine("element line"));
    if (tokens.empty()) continue;
    checkAsciiRecord(tokens, e, in.path(), line);
    ++i;
  }
}

core::PointCloud readAsciiVertices(ByteReader& in, std::size_t& line, const PlyElement& vertex,
                                   const PointLayout& layout, const PlyReadOptions& options) {
  detail::CloudBuilder builder(layout, options.drop_nan);
  detail::readAsciiPoints(in, line, vertex.count, vertex.properties.size(), layout, builder);
  return builder.finish(std::nullopt);
}

/// Walks every element in file order, decoding the vertices and checking the rest.
core::PointCloud readBody(ByteReader& in, std::size_t line, const PlyHeader& header,
                          const PlyReadOptions& options) {
  const PlyElement& vertex = requireVertex(header, in.path(), line);
  const PointLayout layout = vertexLayout(vertex, header.format, in.path());
  const bool ascii = header.format == PlyFormat::kAscii;
  core::PointCloud cloud;
  for (const auto& e : header.elements) {
    if (&e == &vertex) {
      cloud = ascii ? readAsciiVertices(in, line, e, layout, options)
                    : readBinaryVertices(in, e, layout, options);
    } else if (ascii) {
      skipAsciiElement(in, line, e);
    } else {
      skipBinaryElement(in, e, layout.swap);
    }
  }
  return cloud;
}

const char* plyTypeName(const detail::OutField& f) {
  return f.type.kind == ScalarKind::kFloat ? "float" : "ushort";
}

std::string headerText(const std::vector<detail::OutField>& fields, std::size_t n,
                       PlyEncoding encoding) {
  std::string out = "ply\nformat ";
  out.append(encoding == PlyEncoding::kAscii ? "ascii" : "binary_little_endian");
  out.append(" 1.0\ncomment written by dcl-slam\nelement vertex ").append(std::to_string(n));
  for (const auto& f : fields) {
    out.append("\nproperty ").append(plyTypeName(f)).append(" ").append(f.name);
  }
  out.append("\nend_header\n");
  return out;
}

std::string colouredHeader(std::size_t n, PlyEncoding encoding) {
  std::string out = "ply\nformat ";
  out.append(encoding == PlyEncoding::kAscii ? "ascii" : "binary_little_endian");
  out.append(" 1.0\ncomment written by dcl-slam\nelement vertex ").append(std::to_string(n));
  out.append(
      "\nproperty float x\nproperty float y\nproperty float z\nproperty uchar red\n"
      "property uchar green\nproperty uchar blue\nend_header\n");
  return out;
}

/// Records of 15 bytes: three little-endian floats, then three colour bytes.
std::string colouredBinary(std::span<const Eigen::Vector3f> points, std::span<const Rgb> colours) {
  constexpr std::size_t kRecord = 3 * sizeof(float) + 3;
  std::string out(points.size() * kRecord, '\0');
  char* p = out.data();
  for (std::size_t i = 0; i < points.size(); ++i, p += kRecord) {
    std::memcpy(p, points[i].data(), 3 * sizeof(float));
    const std::array<std::uint8_t, 3> rgb{colours[i].r, colours[i].g, colours[i].b};
    std::memcpy(p + 3 * sizeof(float), rgb.data(), 3);
  }
  return out;
}

std::string colouredAscii(std::span<const Eigen::Vector3f> points, std::span<const Rgb> colours) {
  std::string out;
  for (std::size_t i = 0; i < points.size(); ++i) {
    fmt::format_to(std::back_inserter(out), "{} {} {} {} {} {}\n", points[i].x(), points[i].y(),
                   points[i].z(), colours[i].r, colours[i].g, colours[i].b);
  }
  return out;
}

}  // namespace

core::PointCloud readPly(const std::string& path, const PlyReadOptions& options) {
  return decodePly(readFile(path), path, options);
}

core::PointCloud decodePly(std::span<const char> bytes, const std::string& name,
                           const PlyReadOptions& options) {
  if (bytes.empty()) throw core::FileError({name, std::nullopt, 0}, "empty file");
  ByteReader in(bytes, name);
  std::size_t line = 0;
  const PlyHeader header = parsePlyHeader(in, line);
  return readBody(in, line, header, options);
}

void writePly(const std::string& path, const core::PointCloud& cloud,
              const PlyWriteOptions& options) {
  detail::requireConsistent(cloud, path);
  const auto fields = detail::outFields(cloud);
  const bool ascii = options.encoding == PlyEncoding::kAscii;
  detail::writeBytes(path, headerText(fields, cloud.size(), options.encoding) +
                               (ascii ? detail::encodeAscii(cloud, fields)
                                      : detail::encodeBinary(cloud, fields, false)));
}

void writeColouredPly(const std::string& path, std::span<const Eigen::Vector3f> points,
                      std::span<const Rgb> colours, const PlyWriteOptions& options) {
  if (points.size() != colours.size())
    throw core::FileError({path},
                          fmt::format("{} points but {} colours", points.size(), colours.size()));
  const bool ascii = options.encoding == PlyEncoding::kAscii;
  detail::writeBytes(
      path, colouredHeader(points.size(), options.encoding) +
                (ascii ? colouredAscii(points, colours) : colouredBinary(points, colours)));
}

}  // namespace dcl::io
