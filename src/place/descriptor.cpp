#include <string>

#include <dcl/core/error.hpp>
#include <dcl/place/descriptor.hpp>
#include <dcl/place/lidar_iris.hpp>
#include <dcl/place/scan_context.hpp>

namespace dcl::place {

HeightEncoding heightEncodingFor(std::string_view sensor) {
  // The authors' DCL-SLAM code writes `if (n_scan_ = 6)`, which assigns and so
  // sends every sensor down its Livox branch; each name here is compared.
  if (sensor == "hdl64") return HeightEncoding{-5.0, 1.0};
  if (sensor == "vlp16") return HeightEncoding{-2.0, 1.0};
  throw core::Error("LiDAR-Iris: unknown sensor '" + std::string(sensor) +
                    "' (expected hdl64 or vlp16, or set custom_height)");
}

HeightEncoding IrisConfig::heightEncoding() const {
  return custom_height ? height : heightEncodingFor(sensor);
}

std::string_view toString(DescriptorKind kind) {
  return kind == DescriptorKind::kLidarIris ? "iris" : "scancontext";
}

std::optional<DescriptorKind> parseDescriptorKind(std::string_view name) {
  if (name == "iris" || name == "lidar-iris" || name == "lidar_iris")
    return DescriptorKind::kLidarIris;
  if (name == "scancontext" || name == "scan-context" || name == "scan_context")
    return DescriptorKind::kScanContext;
  return std::nullopt;
}

std::unique_ptr<Descriptor> makeDescriptor(const DescriptorConfig& config) {
  const std::optional<DescriptorKind> kind = parseDescriptorKind(config.kind);
  if (!kind)
    throw core::Error("place descriptor: unknown kind '" + config.kind +
                      "' (expected iris or scancontext)");
  if (*kind == DescriptorKind::kLidarIris) return std::make_unique<LidarIris>(config.iris);
  return std::make_unique<ScanContext>(config.scan_context);
}

}  // namespace dcl::place
