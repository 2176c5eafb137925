#include <cmath>

#include <dcl/core/colour.hpp>

namespace dcl::core {

std::array<std::uint8_t, 3> robotColour(std::size_t index) {
  static constexpr std::array<std::array<std::uint8_t, 3>, 10> kPalette = {{{0x1f, 0x77, 0xb4},
                                                                            {0xff, 0x7f, 0x0e},
                                                                            {0x94, 0x67, 0xbd},
                                                                            {0x8c, 0x56, 0x4b},
                                                                            {0xe3, 0x77, 0xc2},
                                                                            {0x17, 0xbe, 0xcf},
                                                                            {0xbc, 0xbd, 0x22},
                                                                            {0x39, 0x3b, 0x79},
                                                                            {0x7b, 0x41, 0x73},
                                                                            {0x8c, 0x6d, 0x31}}};
  if (index < kPalette.size()) return kPalette[index];
  // Beyond the palette: hues a golden angle apart, at the palette's depth.
  const double hue = std::fmod(static_cast<double>(index) * 137.508, 360.0) / 60.0;
  const double x = 1.0 - std::abs(std::fmod(hue, 2.0) - 1.0);
  const int sector = static_cast<int>(hue) % 6;
  const double rgb[6][3] = {{1, x, 0}, {x, 1, 0}, {0, 1, x}, {0, x, 1}, {x, 0, 1}, {1, 0, x}};
  const auto c = [&](int k) {
    return static_cast<std::uint8_t>(std::lround(40 + 180 * rgb[sector][k]));
  };
  return {c(0), c(1), c(2)};
}

}  // namespace dcl::core
