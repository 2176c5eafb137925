#include <cmath>

#include <gtest/gtest.h>

#include <dcl/core/error.hpp>
#include <dcl/place/log_gabor.hpp>

namespace dcl::place {
namespace {

constexpr double kPi = 3.14159265358979323846;

TEST(LogGabor, TransferFollowsEq2) {
  const std::vector<float> g = logGaborTransfer(360, 18.0, 0.75);
  ASSERT_EQ(g.size(), 181U);
  EXPECT_EQ(g[0], 0.0F);           // no DC
  EXPECT_NEAR(g[20], 1.0F, 1e-6);  // centre f0 = 1/18 = bin 20 of 360
  const double expected =
      std::exp(-std::pow(std::log(40.0 / 20.0), 2) / (2 * std::pow(std::log(0.75), 2)));
  EXPECT_NEAR(g[40], expected, 1e-6);  // an octave above
  for (int k = 1; k < 20; ++k) EXPECT_LT(g[k], g[k + 1]);
  for (int k = 20; k < 180; ++k) EXPECT_GT(g[k], g[k + 1]);
}

TEST(LogGabor, ResponseIsTheAnalyticSignalOfATone) {
  LogGaborBank bank(360, {});
  ASSERT_EQ(bank.scales(), 4);
  std::vector<float> row(360);
  for (int j = 0; j < 360; ++j)
    row[j] = 100.0F + 50.0F * static_cast<float>(std::cos(2 * kPi * 20 * j / 360.0));
  std::vector<std::complex<float>> spectrum(181), response(360);
  bank.spectrum(row, spectrum);
  bank.response(spectrum, 0, response);
  // A tone at the finest filter's centre: the (unscaled) response is
  // 360 * 25 * exp(i 2 pi 20 j / 360), the mean (100) filtered out.
  for (int j = 0; j < 360; ++j) {
    const double phase = 2 * kPi * 20 * j / 360.0;
    EXPECT_NEAR(response[j].real(), 9000.0 * std::cos(phase), 1.0) << j;
    EXPECT_NEAR(response[j].imag(), 9000.0 * std::sin(phase), 1.0) << j;
  }
  // Coarser filters (wavelength 18 * 1.6^s) pass less of it.
  double previous = 1e9;
  for (int s = 1; s < 4; ++s) {
    bank.response(spectrum, s, response);
    EXPECT_LT(std::abs(response[0]), previous);
    previous = std::abs(response[0]);
  }
}

TEST(LogGabor, ConstantRowsGiveNoResponse) {
  LogGaborBank bank(360, {});
  std::vector<float> row(360, 42.0F);
  std::vector<std::complex<float>> spectrum(181), response(360);
  bank.spectrum(row, spectrum);
  bank.response(spectrum, 2, response);
  for (const auto& v : response) EXPECT_LT(std::abs(v), 1e-2);
}

TEST(LogGabor, RejectsBadParameters) {
  EXPECT_THROW(LogGaborBank(361, {}), core::Error);
  LogGaborConfig c;
  c.sigma_on_f = 1.5;
  EXPECT_THROW(LogGaborBank(360, c), core::Error);
  LogGaborBank bank(360, {});
  std::vector<float> row(100);
  std::vector<std::complex<float>> spectrum(181);
  EXPECT_THROW(bank.spectrum(row, spectrum), core::Error);
}

}  // namespace
}  // namespace dcl::place
