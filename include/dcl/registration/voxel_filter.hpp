#pragma once

/// Voxel-grid downsampling: one point, the centroid, per occupied voxel.
///
/// Registration costs grow with the number of points while its accuracy
/// depends on the surfaces they sample; a voxel grid evens out the density of
/// a LiDAR scan (dense near the sensor, sparse rings far away) so that every
/// surface patch pulls about equally. The grid is anchored at the origin of the
/// cloud's frame, so two clouds in one frame share voxels, and filtering a
/// filtered cloud again at the same size returns it unchanged (a centroid stays
/// in its voxel).

#include <Eigen/Core>
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

namespace dcl::registration {

/// Voxels further than this many voxel edges from the origin are dropped (the
/// voxel key packs 21 bits an axis): 10 km at 1 cm voxels.
inline constexpr double kMaxVoxelIndex = 1048575.0;

/// What voxelKey() gives for a point that has no voxel.
inline constexpr std::uint64_t kNoVoxel = std::numeric_limits<std::uint64_t>::max();

/// The integer coordinates of the voxel holding `p`, floor(p * inverse_size)
/// per axis, packed into one number (21 bits an axis, x highest), for hash
/// tables of voxels; kNoVoxel when `p` is not finite or beyond kMaxVoxelIndex
/// voxels from the origin.
std::uint64_t voxelKey(const Eigen::Vector3d& p, double inverse_size);

/// The corner (lowest coordinates) of the voxel of edge `voxel_size` with `key`.
Eigen::Vector3d voxelCorner(std::uint64_t key, double voxel_size);

/// A well-mixed hash of a voxel key (the finaliser of MurmurHash3): neighbouring
/// voxels differ in a few low bits of each axis, which must spread over a table.
std::uint64_t hashVoxelKey(std::uint64_t key);

/// The centroid of the points in each occupied voxel of edge `voxel_size` (m),
/// in the order the voxels were first seen, so that the output keeps the scan's
/// locality and is deterministic. Points with a non-finite coordinate and points
/// beyond kMaxVoxelIndex voxels are skipped. Throws core::Error when
/// `voxel_size` is not a positive finite number.
std::vector<Eigen::Vector3d> voxelDownsample(std::span<const Eigen::Vector3f> points,
                                             double voxel_size);

/// As above, for points in double precision.
std::vector<Eigen::Vector3d> voxelDownsample(std::span<const Eigen::Vector3d> points,
                                             double voxel_size);

}  // namespace dcl::registration
