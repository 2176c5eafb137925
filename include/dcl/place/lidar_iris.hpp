#pragma once

/// LiDAR-Iris (Wang et al. 2020; paper §III-B): a scan's bird's-eye view as an
/// 80 x 360 polar image of 8-bit height codes, LoG-Gabor features of its rows
/// (Eq. 2) as bit-packed binary images with a mask, a rotation-invariant row
/// key (Eq. 5), and a match that finds the relative yaw by phase correlation
/// (Eq. 3-4) before the masked normalised Hamming distance (Eq. 6).

#include <complex>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include <dcl/core/point_cloud.hpp>
#include <dcl/place/descriptor.hpp>

namespace dcl::place {

/// The bird's-eye image: rows are radial bins (row 0 nearest), columns angular
/// bins (column j is centred on j * 360/columns degrees counter-clockwise from
/// the sensor's +x axis, as the original's floor(yaw + 0.5)), each cell an
/// 8-bit code of the occupied height slabs.
struct IrisImage {
  int rows = 0;
  int columns = 0;
  std::vector<std::uint8_t> cells{};  ///< rows * columns, row-major

  /// The code at (row, column).
  [[nodiscard]] std::uint8_t at(int row, int column) const {
    return cells[static_cast<std::size_t>(row) * static_cast<std::size_t>(columns) +
                 static_cast<std::size_t>(column)];
  }
  /// Row `row` as a span of `columns` codes.
  [[nodiscard]] std::span<const std::uint8_t> row(int row) const {
    return {cells.data() + static_cast<std::size_t>(row) * static_cast<std::size_t>(columns),
            static_cast<std::size_t>(columns)};
  }
};

/// A LiDAR-Iris description. Feature bits are packed along the angle, 64
/// columns a word, `words` words a row (the padding bits are zero); a row is
/// one (plane, radial bin) pair.
class IrisDescriptor final : public PlaceDescriptor {
 public:
  IrisImage image{};             ///< the occupancy image (what goes on the wire)
  std::vector<float> row_key{};  ///< paper Eq. 5: the L2 norm of each image row
  int scales = 0;                ///< LoG-Gabor filters
  int words = 0;                 ///< 64-bit words per packed row: ceil(columns / 64)
  /// Feature bits: planes [re(scale 0..S-1), im(scale 0..S-1)] x rows x words;
  /// a bit is the sign (> 0) of the response's real or imaginary part.
  std::vector<std::uint64_t> features{};
  /// Mask bits (1 = weak response, ignored by Eq. 6): scales x rows x words,
  /// shared by the real and imaginary planes of a scale.
  std::vector<std::uint64_t> mask{};
  /// Angular spectra for the phase correlation: shift_bands x (columns/2 + 1)
  /// bins, the DFT of the sum of each band's rows.
  std::vector<std::complex<float>> band_spectra{};

  [[nodiscard]] DescriptorKind kind() const override { return DescriptorKind::kLidarIris; }
  [[nodiscard]] std::span<const float> key() const override { return row_key; }

  /// Packed row `row` of feature plane `plane` (0..2*scales-1).
  [[nodiscard]] std::span<const std::uint64_t> featureRow(int plane, int row) const;
  /// Packed mask row `row` of scale `scale`.
  [[nodiscard]] std::span<const std::uint64_t> maskRow(int scale, int row) const;
};

/// Paper §III-B: the bird's-eye image of a scan in its sensor frame. A point at
/// horizontal range d falls in row clamp(floor(d * rows / max_range), 0, rows-1)
/// (points beyond max_range land in the last row, as in the original) and sets
/// the bit of its height slab (config.heightEncoding()). Non-finite points are skipped.
IrisImage makeIrisImage(const core::PointCloud& scan, const IrisConfig& config = {});

/// Paper Eq. 5: k_i = sqrt(sum_j c_ij^2), one value a row, invariant to yaw
/// (a yaw only permutes a row's cells).
std::vector<float> irisRowKey(const IrisImage& image);

/// Describes a scan: image, row key, features, mask and band spectra.
IrisDescriptor describeIris(const core::PointCloud& scan, const IrisConfig& config = {});

/// Describes an image (e.g. one received on the wire). The same image gives
/// the same bits, bit for bit. Throws core::Error when its dimensions do not
/// match the config.
IrisDescriptor describeIrisImage(IrisImage image, const IrisConfig& config = {});

/// Paper Eq. 6, normalised and masked as in the original: the fraction of
/// differing feature bits, over the bits masked in neither, after shifting the
/// query by `shift` columns (query column j compared with candidate column
/// j + shift). 1.0 when every bit is masked.
double irisHammingDistance(const IrisDescriptor& query, const IrisDescriptor& candidate, int shift);

/// Paper Eq. 3-4: the phase correlation of the two images along the angle, one
/// value per shift s in [0, columns): high where the candidate looks like the
/// query rotated by s columns.
std::vector<float> irisShiftCorrelation(const IrisDescriptor& query,
                                        const IrisDescriptor& candidate);

/// Matches a query with a candidate: the best phase-correlation peak for the
/// same driving direction (|yaw| <= 90°) and, when config.match_reverse, for the
/// opposite one; the Hamming distance at each peak; then the better peak and
/// its config.neighbour_shifts neighbours either side, the smallest distance
/// winning. Throws core::Error when the two have different dimensions.
Match matchIris(const IrisDescriptor& query, const IrisDescriptor& candidate,
                const IrisConfig& config = {});

/// LiDAR-Iris behind the Descriptor interface.
class LidarIris final : public Descriptor {
 public:
  /// Throws core::Error on invalid parameters.
  explicit LidarIris(const IrisConfig& config = {});

  [[nodiscard]] const IrisConfig& config() const { return config_; }
  [[nodiscard]] DescriptorKind kind() const override { return DescriptorKind::kLidarIris; }
  [[nodiscard]] std::size_t keySize() const override;
  [[nodiscard]] std::shared_ptr<const PlaceDescriptor> describe(
      const core::PointCloud& scan) const override;
  [[nodiscard]] Match match(const PlaceDescriptor& query,
                            const PlaceDescriptor& candidate) const override;

 private:
  IrisConfig config_;
};

/// Throws core::Error naming the first field that breaks its rule (visit()).
void validate(const IrisConfig& config);

}  // namespace dcl::place
