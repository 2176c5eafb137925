// RGB images and PNG files.

#include <filesystem>

#include <gtest/gtest.h>

#include <dcl/io/image.hpp>

#include "io_test_util.hpp"

namespace dcl::io {
namespace {

Image gradient(int width, int height) {
  Image image(width, height);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x)
      image.set(x, y,
                {static_cast<std::uint8_t>(x * 7), static_cast<std::uint8_t>(y * 11),
                 static_cast<std::uint8_t>((x * y) % 256)});
  return image;
}

TEST(Image, SetGetAndFill) {
  Image image(4, 3, {1, 2, 3});
  EXPECT_EQ(image.width(), 4);
  EXPECT_EQ(image.height(), 3);
  EXPECT_EQ(image.data().size(), 36u);
  EXPECT_EQ(image.get(3, 2), (Rgb{1, 2, 3}));
  image.set(3, 2, {9, 8, 7});
  EXPECT_EQ(image.get(3, 2), (Rgb{9, 8, 7}));
  EXPECT_EQ(image.data()[3 * (2 * 4 + 3)], 9);  // row-major, interleaved RGB
  image.set(-1, 0, {255, 255, 255});            // outside: ignored
  image.set(4, 0, {255, 255, 255});
  EXPECT_EQ(image.get(0, 0), (Rgb{1, 2, 3}));
  EXPECT_THROW((void)image.get(4, 0), core::Error);
  EXPECT_THROW(Image(-1, 2), core::Error);
}

TEST(Image, PngRoundTripIsLossless) {
  const auto dir = test::freshDir("png_round_trip");
  const Image image = gradient(37, 21);  // odd sizes: no row padding assumed
  const std::string path = (dir / "sub" / "g.png").string();
  writePng(path, image);
  EXPECT_FALSE(std::filesystem::exists(path + ".tmp"));
  const std::string bytes = test::readBytes(path);
  ASSERT_GT(bytes.size(), 8u);
  EXPECT_EQ(bytes.substr(1, 3), "PNG");  // the PNG signature
  const Image back = readPng(path);
  ASSERT_EQ(back.width(), 37);
  ASSERT_EQ(back.height(), 21);
  EXPECT_EQ(back.data(), image.data());
}

TEST(Image, WriteFailuresNameTheFileAndKeepTheOldOne) {
  const auto dir = test::freshDir("png_failures");
  const std::string path = (dir / "keep.png").string();
  writePng(path, gradient(3, 3));
  const std::string before = test::readBytes(path);
  const std::string message = test::fileError([&] { writePng(path, Image()); });
  EXPECT_TRUE(test::contains(message, "keep.png"));
  EXPECT_EQ(test::readBytes(path), before);
}

TEST(Image, ReadingSomethingElseIsAFileError) {
  const auto dir = test::freshDir("png_bad");
  const auto path = dir / "not.png";
  test::writeBytes(path, "this is not a PNG file at all");
  EXPECT_TRUE(test::contains(test::fileError([&] { readPng(path.string()); }), "not.png"));
  EXPECT_TRUE(test::contains(test::fileError([&] { readPng((dir / "missing.png").string()); }),
                             "missing.png"));
}

}  // namespace
}  // namespace dcl::io
