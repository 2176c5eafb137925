#pragma once

/// Place descriptors behind one narrow interface (paper §III-B, "Description"
/// and "Search"): LiDAR-Iris, the paper's choice, and Scan Context, the
/// baseline it is compared against. A place index needs two things of a
/// descriptor: a fixed-length, rotation-invariant key for its k-d tree (the
/// LiDAR-Iris row key, the Scan Context ring key) and a pairwise match that
/// returns a distance and the relative yaw.
///
/// Yaw convention, for every descriptor: `Match::yaw_rad` is the yaw of
/// T_query_candidate, the candidate's sensor frame seen from the query's, so
/// that Rz(yaw_rad) is the rotation part of the initial guess for verifying the
/// loop (p_query ~ Rz(yaw_rad) p_candidate, translation aside).

#include <cstddef>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>

#include <dcl/core/config.hpp>
#include <dcl/core/point_cloud.hpp>
#include <dcl/place/log_gabor.hpp>

namespace dcl::place {

/// Which algorithm made a descriptor.
enum class DescriptorKind { kLidarIris, kScanContext };

/// "iris" or "scancontext".
std::string_view toString(DescriptorKind kind);

/// Parses "iris" / "lidar-iris" / "scancontext" / "scan-context"; nullopt otherwise.
std::optional<DescriptorKind> parseDescriptorKind(std::string_view name);

/// Which height slab sets which bit of a LiDAR-Iris bin: bit
/// clamp(ceil((z - lowest) / slab), 0, 7) for a point at height z (m, sensor
/// frame, z up). The defaults are the original's KITTI HDL-64 encoding.
struct HeightEncoding {
  double lowest = -5.0;  ///< m, z at the top of slab 0 (HDL-64: 5 m below the sensor)
  double slab = 1.0;     ///< m, slab height (HDL-64: 1 m)

  /// Lists the fields and their rules (core/config.hpp).
  template <class V>
  void visit(V& v) {
    v.field("lowest", lowest, "m, top of the lowest height slab, sensor frame").finite();
    v.field("slab", slab, "m, height of each of the 8 slabs").positive();
  }
};

/// The height encoding for a sensor model: "hdl64" (KITTI: 1 m slabs from 5 m
/// below the sensor, mounted at 1.73 m, so the ground falls in bit 4) or
/// "vlp16" (±15° vertical field of view at a 0.7-1 m mount: 1 m slabs from 2 m
/// below the sensor, so the ground falls in bit 2 (bit 1 on a downhill slope)
/// and bits 3-7 cover 0-5 m above the sensor, about what a 15° beam reaches
/// within 20 m, where a VLP-16 sees most structure). Each name is compared in
/// full, so no sensor falls into another's branch by accident; other sensors
/// set IrisConfig::custom_height. Throws core::Error for an unknown name.
HeightEncoding heightEncodingFor(std::string_view sensor);

/// LiDAR-Iris parameters (paper §III-B; DESIGN.md §6).
struct IrisConfig {
  static constexpr int kMaxRows = 1024;     ///< radial bins at most
  static constexpr int kMaxColumns = 4096;  ///< angular bins at most

  int rows = 80;          ///< radial bins (paper: 80)
  int columns = 360;      ///< angular bins (paper: 360, 1 degree each)
  double max_range = 80;  ///< m, radial extent; rows are max_range / rows wide (paper: 80 m)
  std::string sensor =
      "hdl64";  ///< picks the height encoding: "hdl64", "vlp16" (see heightEncodingFor)
  bool custom_height = false;  ///< use `height` below instead of the sensor's encoding
  HeightEncoding height{};     ///< used when custom_height is set
  LogGaborConfig log_gabor{};  ///< the feature filters (paper Eq. 2)
  /// Shifts either side of a phase-correlation peak at which the Hamming
  /// distance is also evaluated (the original: 2).
  int neighbour_shifts = 2;
  /// Also test the opposite driving direction (a yaw beyond ±90°), as the
  /// original does; off, only |yaw| <= 90° is searched.
  bool match_reverse = true;
  /// Radial bands of rows whose angular spectra are kept for the phase
  /// correlation (paper Eq. 3-4): rows are summed per band (the DFT is linear),
  /// so a pair costs `rows/bands` times fewer operations than per row.
  int shift_bands = 10;

  /// The effective height encoding (custom or the sensor's).
  [[nodiscard]] HeightEncoding heightEncoding() const;

  /// Lists the fields and their rules (core/config.hpp).
  template <class V>
  void visit(V& v) {
    v.field("rows", rows, "radial bins (paper: 80)").within(1, kMaxRows);
    // The LoG-Gabor filters take each row's real DFT: an even length of 4 at least.
    v.field("columns", columns, "angular bins (paper: 360)")
        .within(4, kMaxColumns)
        .rule(columns % 2 == 0, "must be even");
    v.field("max_range", max_range, "m, radial extent of the image (paper: 80)").positive();
    v.field("sensor", sensor, "height encoding: hdl64 | vlp16").oneOf({"hdl64", "vlp16"});
    v.field("custom_height", custom_height,
            "use the height section instead of the sensor's encoding");
    v.section("height", height, "custom height slabs");
    v.section("log_gabor", log_gabor, "LoG-Gabor feature filters (paper Eq. 2)");
    v.field("neighbour_shifts", neighbour_shifts,
            "shifts either side of the FFT peak tried (original: 2)")
        .nonNegative()
        .rule(neighbour_shifts <= columns / 4,
              "must be at most columns / 4 (" + std::to_string(columns / 4) + ")");
    v.field("match_reverse", match_reverse, "also match the opposite driving direction");
    v.field("shift_bands", shift_bands, "radial bands kept for the phase correlation")
        .positive()
        .atMost(rows, "rows");
  }
};

/// Scan Context parameters (Kim & Kim 2018 defaults).
struct ScanContextConfig {
  static constexpr int kMaxRings = 1024;    ///< radial bins at most
  static constexpr int kMaxSectors = 4096;  ///< angular bins at most

  int rings = 20;         ///< radial bins (Scan Context: 20)
  int sectors = 60;       ///< angular bins (Scan Context: 60, 6 degrees each)
  double max_range = 80;  ///< m (Scan Context: 80)
  double sensor_height =
      2.0;  ///< m, added to z so that bin heights are positive (Scan Context: 2.0)

  /// Lists the fields and their rules (core/config.hpp).
  template <class V>
  void visit(V& v) {
    v.field("rings", rings, "radial bins (Scan Context: 20)").within(1, kMaxRings);
    v.field("sectors", sectors, "angular bins (Scan Context: 60)").within(4, kMaxSectors);
    v.field("max_range", max_range, "m, radial extent (Scan Context: 80)").positive();
    v.field("sensor_height", sensor_height,
            "m, added to z so heights are positive (Scan Context: 2.0)")
        .finite();
  }
};

/// Which descriptor, with the parameters of each.
struct DescriptorConfig {
  std::string kind = "iris";  ///< "iris" (LiDAR-Iris, the paper's) or "scancontext" (baseline)
  IrisConfig iris{};
  ScanContextConfig scan_context{};

  /// Lists the fields and their rules (core/config.hpp).
  template <class V>
  void visit(V& v) {
    v.field("kind", kind, "iris | scancontext")
        .rule(parseDescriptorKind(kind).has_value(), "must be one of iris, scancontext");
    v.section("iris", iris, "LiDAR-Iris");
    v.section("scan_context", scan_context, "Scan Context (baseline)");
  }
};

/// The outcome of comparing two descriptors.
struct Match {
  double distance =
      1.0;  ///< 0 identical .. 1 (LiDAR-Iris: normalised Hamming, Eq. 6; Scan Context: cosine)
  double yaw_rad = 0.0;   ///< yaw of T_query_candidate, in (-pi, pi] (see the file comment)
  bool reversed = false;  ///< the best match was the opposite driving direction (|yaw| > 90°)
  int shift = 0;          ///< columns (sectors) the query was shifted by, in [0, columns)
};

/// One scan's description, immutable once made. Concrete types: IrisDescriptor
/// (lidar_iris.hpp), ScanContextDescriptor (scan_context.hpp).
class PlaceDescriptor {
 public:
  virtual ~PlaceDescriptor() = default;
  /// The algorithm that made it.
  [[nodiscard]] virtual DescriptorKind kind() const = 0;
  /// The rotation-invariant key for the k-d tree (paper Eq. 5 for LiDAR-Iris).
  [[nodiscard]] virtual std::span<const float> key() const = 0;
};

/// A description algorithm: describes scans and matches descriptions. Methods
/// are const and safe to call from several threads at once.
class Descriptor {
 public:
  virtual ~Descriptor() = default;
  /// The algorithm.
  [[nodiscard]] virtual DescriptorKind kind() const = 0;
  /// Length of every key() this descriptor makes.
  [[nodiscard]] virtual std::size_t keySize() const = 0;
  /// Describes a scan in its sensor frame (z up).
  [[nodiscard]] virtual std::shared_ptr<const PlaceDescriptor> describe(
      const core::PointCloud& scan) const = 0;
  /// Compares a query with a candidate. Throws core::Error when either was made
  /// by another algorithm or with other dimensions.
  [[nodiscard]] virtual Match match(const PlaceDescriptor& query,
                                    const PlaceDescriptor& candidate) const = 0;
};

/// The descriptor `config.kind` names. Throws core::Error for an unknown kind
/// or invalid parameters.
std::unique_ptr<Descriptor> makeDescriptor(const DescriptorConfig& config = {});

}  // namespace dcl::place
