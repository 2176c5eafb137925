#include <cstring>

#include <png.h>

#include <dcl/core/error.hpp>
#include <dcl/io/file.hpp>
#include <dcl/io/image.hpp>

namespace dcl::io {

Image::Image(int width, int height, Rgb fill) : width_(width), height_(height) {
  if (width < 0 || height < 0) throw core::Error("image size must not be negative");
  data_.resize(3 * static_cast<std::size_t>(width) * static_cast<std::size_t>(height));
  for (std::size_t i = 0; i < data_.size(); i += 3) {
    data_[i] = fill.r;
    data_[i + 1] = fill.g;
    data_[i + 2] = fill.b;
  }
}

void Image::set(int x, int y, Rgb colour) {
  if (!contains(x, y)) return;
  const std::size_t i = 3 * (static_cast<std::size_t>(y) * width_ + x);
  data_[i] = colour.r;
  data_[i + 1] = colour.g;
  data_[i + 2] = colour.b;
}

Rgb Image::get(int x, int y) const {
  if (!contains(x, y)) throw core::Error("pixel outside the image");
  const std::size_t i = 3 * (static_cast<std::size_t>(y) * width_ + x);
  return {data_[i], data_[i + 1], data_[i + 2]};
}

namespace {

/// A libpng simplified-API descriptor for an 8-bit RGB image.
png_image rgbDescriptor(int width, int height) {
  png_image png;
  std::memset(&png, 0, sizeof(png));
  png.version = PNG_IMAGE_VERSION;
  png.width = static_cast<png_uint_32>(width);
  png.height = static_cast<png_uint_32>(height);
  png.format = PNG_FORMAT_RGB;
  return png;
}

}  // namespace

std::vector<char> encodePng(const Image& image) {
  if (image.empty()) throw core::Error("cannot encode an empty image as PNG");
  png_image png = rgbDescriptor(image.width(), image.height());
  png_alloc_size_t size = 0;
  const void* pixels = image.data().data();
  if (!png_image_write_to_memory(&png, nullptr, &size, 0, pixels, 0, nullptr)) {
    throw core::Error(std::string("PNG encoding failed: ") + png.message);
  }
  std::vector<char> bytes(size);
  if (!png_image_write_to_memory(&png, bytes.data(), &size, 0, pixels, 0, nullptr)) {
    throw core::Error(std::string("PNG encoding failed: ") + png.message);
  }
  bytes.resize(size);
  return bytes;
}

void writePng(const std::string& path, const Image& image) {
  if (image.empty()) throw core::FileError({path}, "cannot write an empty image");
  std::vector<char> bytes;
  try {
    bytes = encodePng(image);
  } catch (const core::Error& e) {
    throw core::FileError({path}, e.what());
  }
  writeFileAtomic(
      path,
      [&](std::ostream& out) {
        out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
      },
      true);
}

Image readPng(const std::string& path) {
  const std::vector<char> bytes = readFile(path);
  png_image png = rgbDescriptor(0, 0);
  if (!png_image_begin_read_from_memory(&png, bytes.data(), bytes.size())) {
    throw core::FileError({path}, std::string("not a readable PNG: ") + png.message);
  }
  png.format = PNG_FORMAT_RGB;
  Image image(static_cast<int>(png.width), static_cast<int>(png.height));
  std::uint8_t* pixels = image.data().data();
  if (!png_image_finish_read(&png, nullptr, pixels, 0, nullptr)) {
    png_image_free(&png);
    throw core::FileError({path}, std::string("PNG decoding failed: ") + png.message);
  }
  return image;
}

}  // namespace dcl::io
