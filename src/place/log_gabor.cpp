#include <cmath>
#include <string>

#include <kiss_fft.h>
#include <kiss_fftr.h>

#include <dcl/core/config.hpp>
#include <dcl/core/error.hpp>
#include <dcl/place/log_gabor.hpp>

namespace dcl::place {

namespace {

void checkLogGabor(bool ok, const std::string& what) {
  if (!ok) throw core::Error("LoG-Gabor: " + what);
}

void validate(int columns, const LogGaborConfig& config) {
  checkLogGabor(columns >= 4 && columns % 2 == 0, "row length must be even and at least 4");
  core::checkConfig(config, "LoG-Gabor config");
}

kiss_fft_cpx* asKiss(std::complex<float>* p) {
  return reinterpret_cast<kiss_fft_cpx*>(p);
}

}  // namespace

std::vector<float> logGaborTransfer(int columns, double wavelength, double sigma_on_f) {
  const int bins = columns / 2 + 1;
  std::vector<float> transfer(static_cast<std::size_t>(bins), 0.0F);
  const double f0 = 1.0 / wavelength;
  const double denominator = 2.0 * std::log(sigma_on_f) * std::log(sigma_on_f);
  // Eq. 2 on the normalised frequency k / columns; bin 0 (DC) stays 0 so the
  // features ignore a ring's mean height and only see its angular structure.
  for (int k = 1; k < bins; ++k) {
    const double f = static_cast<double>(k) / columns;
    const double l = std::log(f / f0);
    transfer[static_cast<std::size_t>(k)] = static_cast<float>(std::exp(-l * l / denominator));
  }
  return transfer;
}

struct LogGaborBank::Impl {
  int columns = 0;
  LogGaborConfig config{};
  std::vector<std::vector<float>> transfers{};
  kiss_fftr_cfg forward = nullptr;
  kiss_fft_cfg inverse = nullptr;
  std::vector<std::complex<float>> full{};  // a whole spectrum, negative frequencies zero

  ~Impl() {
    kiss_fftr_free(forward);
    kiss_fft_free(inverse);
  }
};

LogGaborBank::LogGaborBank(int columns, const LogGaborConfig& config)
    : impl_(std::make_unique<Impl>()) {
  validate(columns, config);
  impl_->columns = columns;
  impl_->config = config;
  double wavelength = config.min_wavelength;
  for (int s = 0; s < config.scales; ++s, wavelength *= config.multiplier)
    impl_->transfers.push_back(logGaborTransfer(columns, wavelength, config.sigma_on_f));
  impl_->forward = kiss_fftr_alloc(columns, 0, nullptr, nullptr);
  impl_->inverse = kiss_fft_alloc(columns, 1, nullptr, nullptr);
  checkLogGabor(impl_->forward != nullptr && impl_->inverse != nullptr,
                "FFT plan allocation failed");
  impl_->full.assign(static_cast<std::size_t>(columns), {0.0F, 0.0F});
}

LogGaborBank::~LogGaborBank() = default;
LogGaborBank::LogGaborBank(LogGaborBank&&) noexcept = default;
LogGaborBank& LogGaborBank::operator=(LogGaborBank&&) noexcept = default;

int LogGaborBank::columns() const {
  return impl_->columns;
}
int LogGaborBank::scales() const {
  return impl_->config.scales;
}
const LogGaborConfig& LogGaborBank::config() const {
  return impl_->config;
}

void LogGaborBank::spectrum(std::span<const float> row, std::span<std::complex<float>> out) {
  checkLogGabor(row.size() == static_cast<std::size_t>(impl_->columns) &&
                    out.size() == static_cast<std::size_t>(impl_->columns / 2 + 1),
                "spectrum: wrong buffer sizes");
  kiss_fftr(impl_->forward, row.data(), asKiss(out.data()));
}

void LogGaborBank::response(std::span<const std::complex<float>> spectrum, int scale,
                            std::span<std::complex<float>> out) {
  const auto bins = static_cast<std::size_t>(impl_->columns / 2 + 1);
  checkLogGabor(spectrum.size() == bins && out.size() == static_cast<std::size_t>(impl_->columns) &&
                    scale >= 0 && scale < scales(),
                "response: wrong buffer sizes or scale");
  // Only the positive frequencies pass (the rest of `full` stays zero), so the
  // response is an analytic signal: its real and imaginary parts are the even
  // and odd filter outputs whose signs make the feature bits.
  const std::vector<float>& transfer = impl_->transfers[static_cast<std::size_t>(scale)];
  for (std::size_t k = 0; k < bins; ++k) impl_->full[k] = spectrum[k] * transfer[k];
  kiss_fft(impl_->inverse, asKiss(impl_->full.data()), asKiss(out.data()));
}

}  // namespace dcl::place
