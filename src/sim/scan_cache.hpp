#pragma once

/// Simulated scans kept on disk between processes: a scan cast once is read
/// back by every later run of the same dataset (the same robots' ground
/// truth, world, sensor and seed) by the same build of the program, instead
/// of being cast again. Each scan is a compressed PCD file of its x y z,
/// intensity, time and ring (float32 and uint16: the same bits as cast).

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include <dcl/core/point_cloud.hpp>
#include <dcl/core/trajectory.hpp>
#include <dcl/io/dataset.hpp>

namespace dcl::sim::detail {

/// What the scans of a simulated dataset are computed by and from: the
/// running program's own bytes (any change of code changes them), the
/// versions of the libraries that cast and round them (Embree, glibc's maths),
/// the dataset as dataset.yaml states it and every robot's ground truth.
/// A 64-bit hash: one folder of the cache per dataset and build.
std::uint64_t simulationKey(const io::DatasetSpec& spec,
                            const std::vector<core::Trajectory>& ground_truth);

/// A folder of cached scans holding at most `max_bytes`: when a store takes
/// it past that, the files read or written longest ago go until it holds
/// three quarters. Any number of processes may share the folder (files are
/// written under temporary names and renamed into place); `load` and `store`
/// may be called from any thread.
class ScanCache {
 public:
  /// The cache of the dataset `key` in `folder` (created when the first scan is stored).
  ScanCache(std::filesystem::path folder, std::uint64_t key, std::uint64_t max_bytes);

  /// Scan `index` of robot `robot`, if cached; a file that cannot be read or
  /// decoded counts as absent (the caller casts the scan and stores it again).
  [[nodiscard]] std::optional<core::PointCloud> load(std::size_t robot, std::size_t index) const;
  /// Keeps scan `index` of robot `robot`. A failure to write (a full disk, a
  /// folder without permission) leaves the cache as it was and is not an
  /// error (the scan was cast all the same): the first is logged as a warning.
  void store(std::size_t robot, std::size_t index, const core::PointCloud& scan);

  /// Scans found and scans stored by this object so far.
  [[nodiscard]] std::uint64_t hits() const { return hits_; }
  [[nodiscard]] std::uint64_t stores() const { return stores_; }

 private:
  [[nodiscard]] std::filesystem::path file(std::size_t robot, std::size_t index) const;
  void trim();

  std::filesystem::path root_;
  std::filesystem::path dataset_folder_;
  std::uint64_t max_bytes_;
  mutable std::atomic<std::uint64_t> hits_{0};
  std::atomic<std::uint64_t> stores_{0};
  std::atomic<bool> warned_{false};  ///< a failed store said so once
  std::mutex trim_mutex_;
  std::uint64_t stored_bytes_ = 0;  ///< written since the folder was last measured
};

}  // namespace dcl::sim::detail
