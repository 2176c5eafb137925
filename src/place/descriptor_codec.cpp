#include <memory>
#include <string>

#include <zstd.h>

#include <dcl/core/config.hpp>
#include <dcl/place/descriptor_codec.hpp>

namespace dcl::place {

namespace {

constexpr std::uint8_t kMagic0 = 'D';
constexpr std::uint8_t kMagic1 = 'I';
constexpr std::uint8_t kKindIrisImage = 1;

void fail(const std::string& what) {
  throw DecodeError("LiDAR-Iris descriptor: " + what);
}

void putU16(std::vector<std::uint8_t>& out, int v) {
  out.push_back(static_cast<std::uint8_t>(v & 0xFF));
  out.push_back(static_cast<std::uint8_t>((v >> 8) & 0xFF));
}

int getU16(std::span<const std::uint8_t> b, std::size_t at) {
  return b[at] | (b[at + 1] << 8);
}

struct CCtxDeleter {
  void operator()(ZSTD_CCtx* c) const { ZSTD_freeCCtx(c); }
};
struct DCtxDeleter {
  void operator()(ZSTD_DCtx* d) const { ZSTD_freeDCtx(d); }
};

/// A zstd frame of `cells`, with its content size and a checksum, so that the
/// receiver can check both before trusting the image.
std::vector<std::uint8_t> compress(const std::vector<std::uint8_t>& cells, int level) {
  std::unique_ptr<ZSTD_CCtx, CCtxDeleter> cctx(ZSTD_createCCtx());
  if (!cctx) throw core::Error("LiDAR-Iris descriptor: zstd context allocation failed");
  ZSTD_CCtx_setParameter(cctx.get(), ZSTD_c_compressionLevel, level);
  ZSTD_CCtx_setParameter(cctx.get(), ZSTD_c_checksumFlag, 1);
  ZSTD_CCtx_setParameter(cctx.get(), ZSTD_c_contentSizeFlag, 1);
  std::vector<std::uint8_t> frame(ZSTD_compressBound(cells.size()));
  const std::size_t n =
      ZSTD_compress2(cctx.get(), frame.data(), frame.size(), cells.data(), cells.size());
  if (ZSTD_isError(n) != 0U)
    throw core::Error(std::string("LiDAR-Iris descriptor: zstd: ") + ZSTD_getErrorName(n));
  frame.resize(n);
  return frame;
}

/// Checks the header; returns the image dimensions it declares.
std::pair<int, int> readHeader(std::span<const std::uint8_t> bytes) {
  if (bytes.size() < kIrisCodecHeaderBytes)
    fail("truncated header (" + std::to_string(bytes.size()) + " bytes)");
  if (bytes[0] != kMagic0 || bytes[1] != kMagic1) fail("bad magic");
  if (bytes[2] != kIrisCodecVersion)
    fail("unsupported version " + std::to_string(bytes[2]) + " (expected " +
         std::to_string(kIrisCodecVersion) + ")");
  if (bytes[3] != kKindIrisImage) fail("unknown payload kind " + std::to_string(bytes[3]));
  const int rows = getU16(bytes, 4);
  const int columns = getU16(bytes, 6);
  if (rows == 0 || columns == 0 ||
      static_cast<std::size_t>(rows) * static_cast<std::size_t>(columns) > kIrisCodecMaxCells)
    fail("bad dimensions " + std::to_string(rows) + " x " + std::to_string(columns));
  return {rows, columns};
}

/// Decompresses the frame after the header into exactly `size` bytes.
std::vector<std::uint8_t> decompress(std::span<const std::uint8_t> frame, std::size_t size) {
  const unsigned long long declared = ZSTD_getFrameContentSize(frame.data(), frame.size());
  if (declared == ZSTD_CONTENTSIZE_ERROR) fail("corrupt or truncated zstd frame");
  if (declared != size) fail("frame size does not match the image dimensions");
  const std::size_t frame_bytes = ZSTD_findFrameCompressedSize(frame.data(), frame.size());
  if (ZSTD_isError(frame_bytes) != 0U) fail("truncated zstd frame");
  if (frame_bytes != frame.size()) fail("trailing bytes after the zstd frame");
  std::unique_ptr<ZSTD_DCtx, DCtxDeleter> dctx(ZSTD_createDCtx());
  if (!dctx) fail("zstd context allocation failed");
  std::vector<std::uint8_t> cells(size);
  const std::size_t n =
      ZSTD_decompressDCtx(dctx.get(), cells.data(), cells.size(), frame.data(), frame.size());
  if (ZSTD_isError(n) != 0U) fail(std::string("zstd: ") + ZSTD_getErrorName(n));
  if (n != size) fail("decoded size does not match the image dimensions");
  return cells;
}

}  // namespace

void validate(const IrisCodecConfig& config) {
  core::checkConfig(config, "LiDAR-Iris codec config");
}

std::vector<std::uint8_t> encodeIrisImage(const IrisImage& image, const IrisCodecConfig& codec) {
  validate(codec);
  const std::size_t cells =
      static_cast<std::size_t>(image.rows) * static_cast<std::size_t>(image.columns);
  if (image.rows <= 0 || image.columns <= 0 || image.rows > 0xFFFF || image.columns > 0xFFFF ||
      cells > kIrisCodecMaxCells || image.cells.size() != cells)
    throw core::Error("LiDAR-Iris descriptor: cannot encode an image of inconsistent dimensions");
  std::vector<std::uint8_t> out{kMagic0, kMagic1, kIrisCodecVersion, kKindIrisImage};
  putU16(out, image.rows);
  putU16(out, image.columns);
  const std::vector<std::uint8_t> frame = compress(image.cells, codec.zstd_level);
  out.insert(out.end(), frame.begin(), frame.end());
  return out;
}

std::vector<std::uint8_t> encodeIris(const IrisDescriptor& descriptor,
                                     const IrisCodecConfig& codec) {
  return encodeIrisImage(descriptor.image, codec);
}

IrisImage decodeIrisImage(std::span<const std::uint8_t> bytes) {
  const auto [rows, columns] = readHeader(bytes);
  const std::size_t size = static_cast<std::size_t>(rows) * static_cast<std::size_t>(columns);
  return IrisImage{rows, columns, decompress(bytes.subspan(kIrisCodecHeaderBytes), size)};
}

IrisDescriptor decodeIris(std::span<const std::uint8_t> bytes, const IrisConfig& config) {
  IrisImage image = decodeIrisImage(bytes);
  if (image.rows != config.rows || image.columns != config.columns)
    fail("image is " + std::to_string(image.rows) + " x " + std::to_string(image.columns) +
         ", expected " + std::to_string(config.rows) + " x " + std::to_string(config.columns));
  return describeIrisImage(std::move(image), config);
}

}  // namespace dcl::place
