#pragma once

/// RGB raster images and PNG files (libpng), for previews and reports.

#include <cstdint>
#include <string>
#include <vector>

namespace dcl::io {

/// One 8-bit RGB colour.
struct Rgb {
  std::uint8_t r = 0;  ///< red
  std::uint8_t g = 0;  ///< green
  std::uint8_t b = 0;  ///< blue

  friend bool operator==(const Rgb&, const Rgb&) = default;
};

/// A width x height RGB8 image, rows top to bottom, pixels left to right.
class Image {
 public:
  Image() = default;
  /// An image filled with `fill`. Throws core::Error for a negative size.
  Image(int width, int height, Rgb fill = {});

  [[nodiscard]] int width() const { return width_; }
  [[nodiscard]] int height() const { return height_; }
  [[nodiscard]] bool empty() const { return width_ == 0 || height_ == 0; }

  /// True when (x, y) is a pixel of the image.
  [[nodiscard]] bool contains(int x, int y) const {
    return x >= 0 && y >= 0 && x < width_ && y < height_;
  }

  /// Sets pixel (x, y); pixels outside the image are ignored (lets shapes clip).
  void set(int x, int y, Rgb colour);

  /// Pixel (x, y); throws core::Error outside the image.
  [[nodiscard]] Rgb get(int x, int y) const;

  /// The interleaved RGB bytes, 3 * width * height of them.
  [[nodiscard]] const std::vector<std::uint8_t>& data() const { return data_; }
  /// The interleaved RGB bytes, for bulk writes (the size must not change).
  [[nodiscard]] std::vector<std::uint8_t>& data() { return data_; }

 private:
  int width_ = 0;
  int height_ = 0;
  std::vector<std::uint8_t> data_;
};

/// `image` as the bytes of an 8-bit RGB PNG (for pages that embed it).
/// Throws core::Error for an empty image or a failed encoding.
std::vector<char> encodePng(const Image& image);

/// Writes `image` as an 8-bit RGB PNG, atomically (temporary file, then rename).
/// Throws core::FileError naming the file for an empty image or a failed write.
void writePng(const std::string& path, const Image& image);

/// Reads a PNG of any colour type as 8-bit RGB (grey expanded, alpha composited onto black).
/// Throws core::FileError naming the file when it cannot be read or decoded.
Image readPng(const std::string& path);

}  // namespace dcl::io
