#include "point_fields.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstring>
#include <limits>

#include <fmt/format.h>

#include <dcl/core/error.hpp>

namespace dcl::io::detail {

namespace {

template <class T>
T loadAs(const char* p, bool swap) {
  std::array<char, sizeof(T)> bytes;
  std::memcpy(bytes.data(), p, sizeof(T));
  if (swap) std::reverse(bytes.begin(), bytes.end());
  return std::bit_cast<T>(bytes);
}

double loadInt(const char* p, std::size_t size, bool swap) {
  switch (size) {
    case 1:
      return loadAs<std::int8_t>(p, swap);
    case 2:
      return loadAs<std::int16_t>(p, swap);
    case 4:
      return loadAs<std::int32_t>(p, swap);
    default:
      return static_cast<double>(loadAs<std::int64_t>(p, swap));
  }
}

double loadUint(const char* p, std::size_t size, bool swap) {
  switch (size) {
    case 1:
      return loadAs<std::uint8_t>(p, swap);
    case 2:
      return loadAs<std::uint16_t>(p, swap);
    case 4:
      return loadAs<std::uint32_t>(p, swap);
    default:
      return static_cast<double>(loadAs<std::uint64_t>(p, swap));
  }
}

bool fitsInteger(double v, ScalarType type) {
  if (type.size >= 8) return true;
  const double bits = static_cast<double>(8 * type.size);
  if (type.kind == ScalarKind::kUint) return v < std::exp2(bits);
  return v >= -std::exp2(bits - 1) && v < std::exp2(bits - 1);
}

ChannelValues parseAsciiPoint(const std::vector<std::string_view>& tokens,
                              const PointLayout& layout, const std::string& path,
                              std::size_t line) {
  ChannelValues v{};
  for (std::size_t c = 0; c < kChannelCount; ++c) {
    const auto& slot = layout.slots[c];
    if (!slot) continue;
    const auto value = parseTyped(tokens[slot->offset], slot->type);
    if (!value) {
      throw core::FileError(
          {path, line, std::nullopt, slot->name},
          fmt::format("'{}' is not a value of the field's type", tokens[slot->offset]));
    }
    v[c] = *value;
  }
  const auto& time = layout.slot(Channel::kTime);
  if (time && time->type.kind != ScalarKind::kFloat) v[4] *= 1e-9;
  return v;
}

float floatValue(const core::PointCloud& cloud, Channel channel, std::size_t i) {
  switch (channel) {
    case Channel::kX:
      return cloud.points[i].x();
    case Channel::kY:
      return cloud.points[i].y();
    case Channel::kZ:
      return cloud.points[i].z();
    case Channel::kIntensity:
      return cloud.intensity[i];
    case Channel::kTime:
      return cloud.time[i];
    case Channel::kRing:
      break;
  }
  return 0.0f;
}

void storeValue(char* dst, const core::PointCloud& cloud, Channel channel, std::size_t i) {
  if (channel == Channel::kRing) {
    std::memcpy(dst, &cloud.ring[i], sizeof(std::uint16_t));
  } else {
    const float v = floatValue(cloud, channel, i);
    std::memcpy(dst, &v, sizeof(float));
  }
}

void appendText(std::string& out, const core::PointCloud& cloud, Channel channel, std::size_t i) {
  std::array<char, 32> buf{};
  const auto result =
      channel == Channel::kRing
          ? std::to_chars(buf.data(), buf.data() + buf.size(), cloud.ring[i])
          : std::to_chars(buf.data(), buf.data() + buf.size(), floatValue(cloud, channel, i));
  out.append(buf.data(), result.ptr);
}

}  // namespace

bool isValid(ScalarType type) {
  if (type.kind == ScalarKind::kFloat) return type.size == 4 || type.size == 8;
  return type.size == 1 || type.size == 2 || type.size == 4 || type.size == 8;
}

double loadScalar(const char* p, ScalarType type, bool swap) {
  switch (type.kind) {
    case ScalarKind::kFloat:
      return type.size == 4 ? loadAs<float>(p, swap) : loadAs<double>(p, swap);
    case ScalarKind::kInt:
      return loadInt(p, type.size, swap);
    case ScalarKind::kUint:
      break;
  }
  return loadUint(p, type.size, swap);
}

std::optional<double> parseTyped(std::string_view token, ScalarType type) {
  if (type.kind == ScalarKind::kFloat) return parseNumber<double>(token);
  std::optional<double> v;
  if (type.kind == ScalarKind::kInt) {
    if (auto i = parseNumber<std::int64_t>(token)) v = static_cast<double>(*i);
  } else if (auto u = parseNumber<std::uint64_t>(token)) {
    v = static_cast<double>(*u);
  }
  if (v && !fitsInteger(*v, type)) return std::nullopt;
  return v;
}

std::optional<std::size_t> checkedMul(std::size_t a, std::size_t b) {
  if (a != 0 && b > std::numeric_limits<std::size_t>::max() / a) return std::nullopt;
  return a * b;
}

std::optional<Channel> channelOf(std::string_view name) {
  if (name == "x") return Channel::kX;
  if (name == "y") return Channel::kY;
  if (name == "z") return Channel::kZ;
  if (name == "intensity" || name == "i") return Channel::kIntensity;
  if (name == "time" || name == "t" || name == "timestamp") return Channel::kTime;
  if (name == "ring") return Channel::kRing;
  return std::nullopt;
}

void PointLayout::assign(Channel c, FieldSlot s) {
  auto& target = slots[static_cast<std::size_t>(c)];
  if (!target) target = std::move(s);
}

std::optional<std::string> PointLayout::missingXyz() const {
  if (!slot(Channel::kX)) return "x";
  if (!slot(Channel::kY)) return "y";
  if (!slot(Channel::kZ)) return "z";
  return std::nullopt;
}

std::optional<std::size_t> bytesNeeded(const PointLayout& layout, std::size_t n) {
  if (n == 0) return 0;
  std::size_t need = 0;
  for (const auto& s : layout.slots) {
    if (!s) continue;
    const auto span = checkedMul(n - 1, s->stride);
    const std::size_t end_of_first = s->offset + s->type.size;
    if (!span || end_of_first < s->offset ||
        *span > std::numeric_limits<std::size_t>::max() - end_of_first) {
      return std::nullopt;
    }
    need = std::max(need, end_of_first + *span);
  }
  return need;
}

CloudBuilder::CloudBuilder(const PointLayout& layout, bool drop_nan)
    : drop_nan_(drop_nan),
      has_intensity_(layout.slot(Channel::kIntensity).has_value()),
      has_time_(layout.slot(Channel::kTime).has_value()),
      has_ring_(layout.slot(Channel::kRing).has_value()) {}

void CloudBuilder::reserve(std::size_t n) {
  cloud_.points.reserve(n);
  if (has_intensity_) cloud_.intensity.reserve(n);
  if (has_time_) times_.reserve(n);
  if (has_ring_) cloud_.ring.reserve(n);
}

std::optional<std::string> CloudBuilder::add(const ChannelValues& v) {
  if (drop_nan_ && !(std::isfinite(v[0]) && std::isfinite(v[1]) && std::isfinite(v[2]))) {
    return std::nullopt;
  }
  const double ring = v[static_cast<std::size_t>(Channel::kRing)];
  if (has_ring_ && !(ring >= 0.0 && ring <= 65535.0 && ring == std::floor(ring))) {
    return fmt::format("ring {} is not an integer in 0..65535", ring);
  }
  cloud_.points.emplace_back(static_cast<float>(v[0]), static_cast<float>(v[1]),
                             static_cast<float>(v[2]));
  if (has_intensity_) cloud_.intensity.push_back(static_cast<float>(v[3]));
  if (has_time_) times_.push_back(v[4]);
  if (has_ring_) cloud_.ring.push_back(static_cast<std::uint16_t>(ring));
  return std::nullopt;
}

core::PointCloud CloudBuilder::finish(std::optional<double> stamp) {
  const bool absolute = std::any_of(times_.begin(), times_.end(),
                                    [](double t) { return std::abs(t) > kAbsoluteTimeThreshold; });
  double origin = 0.0;
  if (absolute) origin = stamp ? *stamp : *std::min_element(times_.begin(), times_.end());
  cloud_.time.reserve(times_.size());
  for (double t : times_) cloud_.time.push_back(static_cast<float>(t - origin));
  return std::move(cloud_);
}

ChannelValues loadPoint(const char* base, std::size_t i, const PointLayout& layout) {
  ChannelValues v{};
  for (std::size_t c = 0; c < kChannelCount; ++c) {
    const auto& s = layout.slots[c];
    if (s) v[c] = loadScalar(base + s->offset + i * s->stride, s->type, layout.swap);
  }
  const auto& time = layout.slot(Channel::kTime);
  if (time && time->type.kind != ScalarKind::kFloat) v[4] *= 1e-9;
  return v;
}

void decodeBinaryPoints(std::span<const char> data, std::size_t n, const PointLayout& layout,
                        CloudBuilder& builder, const std::string& path, std::size_t data_offset) {
  const auto need = bytesNeeded(layout, n);
  if (!need || *need > data.size()) {
    throw core::FileError(
        {path, std::nullopt, data_offset},
        fmt::format("{} points need more than the {} bytes of data", n, data.size()));
  }
  builder.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    if (auto error = builder.add(loadPoint(data.data(), i, layout))) {
      throw core::FileError({path, std::nullopt, data_offset, "ring"},
                            fmt::format("point {}: {}", i, *error));
    }
  }
}

void readAsciiPoints(ByteReader& in, std::size_t& line, std::size_t n, std::size_t tokens_per_point,
                     const PointLayout& layout, CloudBuilder& builder) {
  builder.reserve(std::min(n, in.remaining() / 6));
  for (std::size_t i = 0; i < n;) {
    if (in.atEnd()) {
      throw core::FileError({in.path(), line},
                            fmt::format("truncated data: expected {} points, found {}", n, i));
    }
    ++line;
    const auto tokens = splitWhitespace(in.readLine("point line"));
    if (tokens.empty()) continue;
    if (tokens.size() != tokens_per_point) {
      throw core::FileError({in.path(), line}, fmt::format("expected {} values, found {}",
                                                           tokens_per_point, tokens.size()));
    }
    if (auto error = builder.add(parseAsciiPoint(tokens, layout, in.path(), line))) {
      throw core::FileError({in.path(), line, std::nullopt, "ring"}, *error);
    }
    ++i;
  }
}

std::vector<OutField> outFields(const core::PointCloud& cloud) {
  const ScalarType f4{ScalarKind::kFloat, 4};
  std::vector<OutField> fields = {
      {Channel::kX, "x", f4}, {Channel::kY, "y", f4}, {Channel::kZ, "z", f4}};
  if (cloud.hasIntensity()) fields.push_back({Channel::kIntensity, "intensity", f4});
  if (cloud.hasTime()) fields.push_back({Channel::kTime, "time", f4});
  if (cloud.hasRing()) fields.push_back({Channel::kRing, "ring", {ScalarKind::kUint, 2}});
  return fields;
}

std::string encodeAscii(const core::PointCloud& cloud, const std::vector<OutField>& fields) {
  std::string out;
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    for (std::size_t f = 0; f < fields.size(); ++f) {
      if (f > 0) out += ' ';
      appendText(out, cloud, fields[f].channel, i);
    }
    out += '\n';
  }
  return out;
}

std::string encodeBinary(const core::PointCloud& cloud, const std::vector<OutField>& fields,
                         bool by_field) {
  std::size_t record = 0;
  for (const auto& f : fields) record += f.type.size;
  const std::size_t n = cloud.size();
  std::string out(n * record, '\0');
  std::size_t offset = 0;
  for (const auto& f : fields) {
    for (std::size_t i = 0; i < n; ++i) {
      const std::size_t at = by_field ? offset * n + i * f.type.size : i * record + offset;
      storeValue(out.data() + at, cloud, f.channel, i);
    }
    offset += f.type.size;
  }
  return out;
}

void requireConsistent(const core::PointCloud& cloud, const std::string& path) {
  if (!cloud.consistent()) {
    throw core::FileError({path}, "cannot write a cloud whose channels differ in length");
  }
}

void writeBytes(const std::string& path, const std::string& bytes) {
  writeFileAtomic(
      path,
      [&](std::ostream& out) {
        out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
      },
      true);
}

}  // namespace dcl::io::detail
