#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <limits>
#include <memory>
#include <string>
#include <utility>

#include <zstd.h>

#include <dcl/core/config.hpp>
#include <dcl/registration/cloud_codec.hpp>
#include <dcl/registration/voxel_filter.hpp>

namespace dcl::registration {
namespace {

constexpr std::uint8_t kMagic0 = 'D';
constexpr std::uint8_t kMagic1 = 'V';
constexpr int kMaxOffset = 32767;  // quantised coordinates are in [-32767, 32767]
constexpr std::size_t kBytesPerPoint = 6;

[[noreturn]] void fail(const std::string& what) {
  throw CloudDecodeError("verification cloud: " + what);
}

void require(bool ok, const std::string& what) {
  if (!ok) throw core::Error("verification cloud: " + what);
}

struct CCtxDeleter {
  void operator()(ZSTD_CCtx* c) const { ZSTD_freeCCtx(c); }
};
struct DCtxDeleter {
  void operator()(ZSTD_DCtx* d) const { ZSTD_freeDCtx(d); }
};

/// A point on the quantisation grid.
using GridPoint = std::array<std::int16_t, 3>;

/// The points to send: finite, within range, voxel-filtered.
std::vector<Eigen::Vector3d> selectPoints(const core::PointCloud& cloud,
                                          const CloudCodecConfig& config) {
  std::vector<Eigen::Vector3d> points;
  points.reserve(cloud.size());
  const double max_range2 = config.max_range * config.max_range;
  for (const Eigen::Vector3f& p : cloud.points) {
    const Eigen::Vector3d q = p.cast<double>();
    if (!q.allFinite() || (config.max_range > 0.0 && q.squaredNorm() > max_range2)) continue;
    points.push_back(q);
  }
  return config.voxel_size > 0.0 ? voxelDownsample(points, config.voxel_size) : points;
}

/// The step (as stored, in float) that reaches every point within kMaxOffset steps.
float quantisationStep(const std::vector<Eigen::Vector3d>& points, double resolution) {
  double extent = 0.0;
  for (const Eigen::Vector3d& p : points) extent = std::max(extent, p.cwiseAbs().maxCoeff());
  auto step = static_cast<float>(std::max(resolution, extent / kMaxOffset));
  while (static_cast<double>(step) * kMaxOffset < extent)
    step = std::nextafter(step, std::numeric_limits<float>::infinity());
  require(static_cast<double>(step) <= kCloudCodecMaxResolution,
          "cloud extent " + std::to_string(extent) + " m is too large to quantise");
  return step;
}

/// Spreads the 16 bits of `v` to every third bit (for a 48-bit Morton code).
std::uint64_t spread(std::uint16_t v) {
  std::uint64_t x = v;
  x = (x | (x << 16)) & 0x0000FF0000FFULL;
  x = (x | (x << 8)) & 0x00F00F00F00FULL;
  x = (x | (x << 4)) & 0x0C30C30C30C3ULL;
  x = (x | (x << 2)) & 0x249249249249ULL;
  return x;
}

std::uint64_t morton(const GridPoint& g) {
  auto biased = [](std::int16_t c) { return static_cast<std::uint16_t>(c + 32768); };
  return spread(biased(g[0])) | (spread(biased(g[1])) << 1) | (spread(biased(g[2])) << 2);
}

/// The points on the grid, in Morton order.
std::vector<GridPoint> quantise(const std::vector<Eigen::Vector3d>& points, float step) {
  std::vector<std::pair<std::uint64_t, GridPoint>> keyed;
  keyed.reserve(points.size());
  for (const Eigen::Vector3d& p : points) {
    GridPoint g{};
    for (int axis = 0; axis < 3; ++axis) {
      const long q = std::lround(p[axis] / static_cast<double>(step));
      g[static_cast<std::size_t>(axis)] = static_cast<std::int16_t>(std::clamp(q, -32767L, 32767L));
    }
    keyed.emplace_back(morton(g), g);
  }
  std::sort(keyed.begin(), keyed.end());
  std::vector<GridPoint> grid(keyed.size());
  std::transform(keyed.begin(), keyed.end(), grid.begin(), [](const auto& k) { return k.second; });
  return grid;
}

/// Zigzag of a 16-bit difference: small magnitudes of either sign become small codes.
std::uint16_t zigzag(std::uint16_t delta) {
  const auto d = static_cast<std::int16_t>(delta);
  return static_cast<std::uint16_t>((static_cast<std::uint16_t>(d) << 1) ^
                                    static_cast<std::uint16_t>(d >> 15));
}

std::uint16_t unzigzag(std::uint16_t code) {
  return static_cast<std::uint16_t>((code >> 1) ^ static_cast<std::uint16_t>(-(code & 1)));
}

/// Delta-coded, zigzag-mapped byte planes: plane 2 axis + 0 low bytes, 2 axis + 1 high bytes.
std::vector<std::uint8_t> toPlanes(const std::vector<GridPoint>& grid) {
  const std::size_t n = grid.size();
  std::vector<std::uint8_t> planes(kBytesPerPoint * n);
  for (std::size_t axis = 0; axis < 3; ++axis) {
    std::uint16_t previous = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const auto value = static_cast<std::uint16_t>(grid[i][axis]);
      const std::uint16_t code = zigzag(static_cast<std::uint16_t>(value - previous));
      previous = value;
      planes[(2 * axis) * n + i] = static_cast<std::uint8_t>(code & 0xFF);
      planes[(2 * axis + 1) * n + i] = static_cast<std::uint8_t>(code >> 8);
    }
  }
  return planes;
}

core::PointCloud fromPlanes(const std::vector<std::uint8_t>& planes, std::size_t n, float step) {
  core::PointCloud cloud;
  cloud.points.resize(n);
  for (std::size_t axis = 0; axis < 3; ++axis) {
    std::uint16_t value = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const auto code = static_cast<std::uint16_t>(planes[(2 * axis) * n + i] |
                                                   (planes[(2 * axis + 1) * n + i] << 8));
      value = static_cast<std::uint16_t>(value + unzigzag(code));
      cloud.points[i][static_cast<Eigen::Index>(axis)] = static_cast<float>(
          static_cast<double>(static_cast<std::int16_t>(value)) * static_cast<double>(step));
    }
  }
  return cloud;
}

std::vector<std::uint8_t> compress(const std::vector<std::uint8_t>& bytes, int level) {
  std::unique_ptr<ZSTD_CCtx, CCtxDeleter> cctx(ZSTD_createCCtx());
  require(cctx != nullptr, "zstd context allocation failed");
  ZSTD_CCtx_setParameter(cctx.get(), ZSTD_c_compressionLevel, level);
  ZSTD_CCtx_setParameter(cctx.get(), ZSTD_c_checksumFlag, 1);
  ZSTD_CCtx_setParameter(cctx.get(), ZSTD_c_contentSizeFlag, 1);
  std::vector<std::uint8_t> frame(ZSTD_compressBound(bytes.size()));
  const std::size_t n =
      ZSTD_compress2(cctx.get(), frame.data(), frame.size(), bytes.data(), bytes.size());
  require(ZSTD_isError(n) == 0U, std::string("zstd: ") + ZSTD_getErrorName(n));
  frame.resize(n);
  return frame;
}

std::vector<std::uint8_t> decompress(std::span<const std::uint8_t> frame, std::size_t size) {
  const unsigned long long declared = ZSTD_getFrameContentSize(frame.data(), frame.size());
  if (declared == ZSTD_CONTENTSIZE_ERROR || declared == ZSTD_CONTENTSIZE_UNKNOWN)
    fail("corrupt or truncated zstd frame");
  if (declared != size) fail("frame size does not match the point count");
  const std::size_t frame_bytes = ZSTD_findFrameCompressedSize(frame.data(), frame.size());
  if (ZSTD_isError(frame_bytes) != 0U) fail("truncated zstd frame");
  if (frame_bytes != frame.size()) fail("trailing bytes after the zstd frame");
  std::unique_ptr<ZSTD_DCtx, DCtxDeleter> dctx(ZSTD_createDCtx());
  if (!dctx) fail("zstd context allocation failed");
  std::vector<std::uint8_t> bytes(size);
  const std::size_t n =
      ZSTD_decompressDCtx(dctx.get(), bytes.data(), bytes.size(), frame.data(), frame.size());
  if (ZSTD_isError(n) != 0U) fail(std::string("zstd: ") + ZSTD_getErrorName(n));
  if (n != size) fail("decoded size does not match the point count");
  return bytes;
}

void putU32(std::vector<std::uint8_t>& out, std::uint32_t v) {
  for (int k = 0; k < 4; ++k) out.push_back(static_cast<std::uint8_t>(v >> (8 * k)));
}

std::uint32_t getU32(std::span<const std::uint8_t> b, std::size_t at) {
  std::uint32_t v = 0;
  for (int k = 0; k < 4; ++k) v |= static_cast<std::uint32_t>(b[at + k]) << (8 * k);
  return v;
}

/// Checks the header; returns the quantisation step and the point count.
std::pair<float, std::uint32_t> readHeader(std::span<const std::uint8_t> bytes) {
  if (bytes.size() < kCloudCodecHeaderBytes)
    fail("truncated header (" + std::to_string(bytes.size()) + " bytes)");
  if (bytes[0] != kMagic0 || bytes[1] != kMagic1) fail("bad magic");
  if (bytes[2] != kCloudCodecVersion)
    fail("unsupported version " + std::to_string(bytes[2]) + " (expected " +
         std::to_string(kCloudCodecVersion) + ")");
  if (bytes[3] != 0) fail("unknown flags " + std::to_string(bytes[3]));
  const float step = std::bit_cast<float>(getU32(bytes, 4));
  if (!(static_cast<double>(step) >= kCloudCodecMinResolution) ||
      !(static_cast<double>(step) <= kCloudCodecMaxResolution))
    fail("invalid resolution " + std::to_string(step) + " m");
  const std::uint32_t count = getU32(bytes, 8);
  if (count > kCloudCodecMaxPoints)
    fail("point count " + std::to_string(count) + " over the limit of " +
         std::to_string(kCloudCodecMaxPoints));
  return {step, count};
}

}  // namespace

void validate(const CloudCodecConfig& config) {
  core::checkConfig(config, "verification cloud config");
}

std::vector<std::uint8_t> encodeVerificationCloud(const core::PointCloud& cloud,
                                                  const CloudCodecConfig& config) {
  validate(config);
  const std::vector<Eigen::Vector3d> points = selectPoints(cloud, config);
  require(points.size() <= kCloudCodecMaxPoints,
          std::to_string(points.size()) + " points are more than a message may carry");
  const float step = quantisationStep(points, config.resolution);
  std::vector<std::uint8_t> out{kMagic0, kMagic1, kCloudCodecVersion, 0};
  putU32(out, std::bit_cast<std::uint32_t>(step));
  putU32(out, static_cast<std::uint32_t>(points.size()));
  const std::vector<std::uint8_t> frame =
      compress(toPlanes(quantise(points, step)), config.zstd_level);
  out.insert(out.end(), frame.begin(), frame.end());
  return out;
}

core::PointCloud decodeVerificationCloud(std::span<const std::uint8_t> bytes) {
  const auto [step, count] = readHeader(bytes);
  const std::vector<std::uint8_t> planes =
      decompress(bytes.subspan(kCloudCodecHeaderBytes), kBytesPerPoint * count);
  return fromPlanes(planes, count, step);
}

}  // namespace dcl::registration
