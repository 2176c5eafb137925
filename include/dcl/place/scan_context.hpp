#pragma once

/// Scan Context (Kim & Kim, IROS 2018), the baseline the paper compares
/// LiDAR-Iris against: a 20 x 60 polar grid of the maximum point height per
/// bin, a ring key (the mean of each ring, invariant to yaw) for the k-d tree,
/// and a distance that is the mean column-wise cosine distance at the best
/// column shift.

#include <memory>
#include <span>
#include <vector>

#include <dcl/core/point_cloud.hpp>
#include <dcl/place/descriptor.hpp>

namespace dcl::place {

/// A Scan Context description.
class ScanContextDescriptor final : public PlaceDescriptor {
 public:
  int rings = 0;
  int sectors = 0;
  /// rings x sectors, row-major: the highest z + sensor_height in each bin, 0
  /// when empty. Sector j covers [j, j+1) * 360/sectors degrees from +x.
  std::vector<float> cells{};
  std::vector<float> ring_key{};  ///< the mean of each ring (row)

  [[nodiscard]] DescriptorKind kind() const override { return DescriptorKind::kScanContext; }
  [[nodiscard]] std::span<const float> key() const override { return ring_key; }

  /// The value at (ring, sector).
  [[nodiscard]] float at(int ring, int sector) const {
    return cells[static_cast<std::size_t>(ring) * static_cast<std::size_t>(sectors) +
                 static_cast<std::size_t>(sector)];
  }
};

/// Describes a scan in its sensor frame (z up). Points beyond max_range and
/// non-finite points are ignored.
ScanContextDescriptor describeScanContext(const core::PointCloud& scan,
                                          const ScanContextConfig& config = {});

/// Scan Context's distance at one shift: the mean over sectors non-empty in
/// both of 1 - cos(query sector j, candidate sector j + shift); 1.0 when no
/// sector is non-empty in both.
double scanContextDistance(const ScanContextDescriptor& query,
                           const ScanContextDescriptor& candidate, int shift);

/// The smallest scanContextDistance over all shifts, with the yaw it implies
/// (reversed when |yaw| > 90°). Throws core::Error on different dimensions.
Match matchScanContext(const ScanContextDescriptor& query, const ScanContextDescriptor& candidate);

/// Scan Context behind the Descriptor interface.
class ScanContext final : public Descriptor {
 public:
  /// Throws core::Error on invalid parameters.
  explicit ScanContext(const ScanContextConfig& config = {});

  [[nodiscard]] const ScanContextConfig& config() const { return config_; }
  [[nodiscard]] DescriptorKind kind() const override { return DescriptorKind::kScanContext; }
  [[nodiscard]] std::size_t keySize() const override;
  [[nodiscard]] std::shared_ptr<const PlaceDescriptor> describe(
      const core::PointCloud& scan) const override;
  [[nodiscard]] Match match(const PlaceDescriptor& query,
                            const PlaceDescriptor& candidate) const override;

 private:
  ScanContextConfig config_;
};

}  // namespace dcl::place
