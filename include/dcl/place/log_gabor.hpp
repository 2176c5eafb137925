#pragma once

/// The 1D LoG-Gabor filter bank of LiDAR-Iris (paper Eq. 2), applied along
/// each row of the bird's-eye image in the frequency domain. A log-Gabor has
/// no DC response and a Gaussian profile on a log-frequency axis, so it
/// responds to the angular structure of a ring rather than to its mean
/// height; keeping only the positive frequencies makes the response an
/// analytic signal whose real and imaginary signs are the feature bits.

#include <complex>
#include <memory>
#include <span>
#include <vector>

#include <dcl/core/config.hpp>

namespace dcl::place {

/// Parameters of the filter bank (paper §III-B and the original LiDAR-Iris).
struct LogGaborConfig {
  static constexpr int kMaxScales = 16;  ///< filters at most

  int scales = 4;              ///< number of filters (paper: 4)
  double min_wavelength = 18;  ///< columns, wavelength of the finest filter (paper: 18)
  double multiplier = 1.6;     ///< wavelength ratio between successive filters (paper: 1.6)
  double sigma_on_f = 0.75;    ///< sigma / f0, the bandwidth in Eq. 2 (paper: 0.75)
  double mask_threshold =
      1e-4;  ///< responses with a magnitude below this are masked (original: 1e-4)

  /// Lists the fields and their rules (core/config.hpp).
  template <class V>
  void visit(V& v) {
    v.field("scales", scales, "number of LoG-Gabor filters (paper: 4)").within(1, kMaxScales);
    // Two columns: the shortest wavelength a row of samples holds (Nyquist).
    v.field("min_wavelength", min_wavelength,
            "columns, wavelength of the finest filter (paper: 18)")
        .atLeast(2.0);
    v.field("multiplier", multiplier, "wavelength ratio between filters (paper: 1.6)")
        .greaterThan(1.0);
    v.field("sigma_on_f", sigma_on_f, "sigma / f0, filter bandwidth of Eq. 2 (paper: 0.75)")
        .within(0.0, 1.0, core::Interval::open);
    v.field("mask_threshold", mask_threshold, "response magnitudes below this are masked")
        .nonNegative();
  }
};

/// Eq. 2 sampled at the DFT bins 0..columns/2 of a row of `columns` samples:
/// G(k) = exp(-ln^2(f/f0) / (2 ln^2(sigma/f0))) with f = k/columns and
/// f0 = 1/wavelength; G(0) = 0 (no DC). The negative frequencies are zero.
std::vector<float> logGaborTransfer(int columns, double wavelength, double sigma_on_f);

/// The filter bank for rows of a fixed length, with its FFT plans (kissfft).
/// One instance must not be used by two threads at once (the plans keep
/// scratch buffers); make one per thread.
class LogGaborBank {
 public:
  /// A bank for rows of `columns` samples (even, >= 4). Throws core::Error on bad parameters.
  LogGaborBank(int columns, const LogGaborConfig& config);
  ~LogGaborBank();
  LogGaborBank(LogGaborBank&&) noexcept;
  LogGaborBank& operator=(LogGaborBank&&) noexcept;

  /// Samples per row.
  [[nodiscard]] int columns() const;
  /// Number of filters.
  [[nodiscard]] int scales() const;
  /// The configuration the bank was built with.
  [[nodiscard]] const LogGaborConfig& config() const;

  /// The DFT of a real row (`columns` samples) at bins 0..columns/2.
  void spectrum(std::span<const float> row, std::span<std::complex<float>> out);

  /// The complex response of filter `scale` (0 = finest) to a row given by its
  /// spectrum (bins 0..columns/2): the unscaled inverse DFT of G_scale times the
  /// spectrum, `columns` values.
  void response(std::span<const std::complex<float>> spectrum, int scale,
                std::span<std::complex<float>> out);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace dcl::place
