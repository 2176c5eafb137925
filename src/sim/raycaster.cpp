#include "raycaster.hpp"

#include <algorithm>
#include <cstring>
#include <string>
#include <vector>

#include <embree3/rtcore.h>

#include <dcl/core/error.hpp>

namespace dcl::sim {
namespace {

/// The first error Embree reported through the device callback, with its text.
struct DeviceErrorLog {
  std::string message;  ///< empty while nothing went wrong
};

void recordDeviceError(void* user, RTCError code, const char* text) {
  auto* log = static_cast<DeviceErrorLog*>(user);
  if (!log->message.empty()) return;
  log->message = "error " + std::to_string(static_cast<int>(code)) + ": " + (text ? text : "");
}

struct DeviceDeleter {
  void operator()(RTCDeviceTy* device) const { rtcReleaseDevice(device); }
};
struct SceneDeleter {
  void operator()(RTCSceneTy* scene) const { rtcReleaseScene(scene); }
};
using DevicePtr = std::unique_ptr<RTCDeviceTy, DeviceDeleter>;
using ScenePtr = std::unique_ptr<RTCSceneTy, SceneDeleter>;

/// Refuses worlds Embree would read out of bounds.
void checkWorld(const World& world) {
  if (world.surfaces.size() != world.triangles.size())
    throw core::Error("world has " + std::to_string(world.triangles.size()) + " triangles but " +
                      std::to_string(world.surfaces.size()) + " surfaces");
  const auto n = world.vertices.size();
  for (const auto& t : world.triangles) {
    if (t[0] >= n || t[1] >= n || t[2] >= n)
      throw core::Error("world triangle refers to a vertex past the " + std::to_string(n) +
                        " vertices");
  }
}

/// Embree picks its kernels by the CPU it runs on (SSE, AVX2, AVX-512), and
/// their arithmetic differs in the last bits: the same scan cast on two
/// machines differed in most of its points, enough to turn a tracked turn
/// into a lost one. Pinned to SSE2, the kernels every x86-64 CPU runs, a
/// simulated dataset is the same bits everywhere (`ctest -R ScanChecksums`,
/// which also passes with glibc's own AVX2 and FMA paths switched off).
/// It costs speed: an HDL-64 sweep takes about 1.6 times as long as with
/// AVX-512 (BENCHMARKS.md, "Simulator").
constexpr const char* kDeviceConfig = "isa=sse2";

/// Rays per packet. On this project's machine (AVX-512) a whole HDL-64 sweep
/// of a 10^5-triangle street took 12.3 ms in 16-ray packets of a column's
/// neighbouring beams, 13.3 ms as a stream (rtcIntersect1M) and 24.6 ms one
/// ray at a time (rtcIntersect1), one core.
constexpr int kPacket = 16;

/// HIGH (spatial splits) traced the 10^5-triangle city of bench_sim 2 % faster
/// than MEDIUM and built it in 20 ms instead of 14: worth it, a world is built
/// once and cast thousands of times.
constexpr RTCBuildQuality kBuildQuality = RTC_BUILD_QUALITY_HIGH;

/// Fills lane `lane` of a 16-ray packet.
void loadLane(RTCRayHit16& packet, int lane, const Ray& ray, float max_range) {
  auto& r = packet.ray;
  r.org_x[lane] = ray.origin.x();
  r.org_y[lane] = ray.origin.y();
  r.org_z[lane] = ray.origin.z();
  r.dir_x[lane] = ray.direction.x();
  r.dir_y[lane] = ray.direction.y();
  r.dir_z[lane] = ray.direction.z();
  r.tnear[lane] = 0.0f;
  r.tfar[lane] = max_range;
  r.time[lane] = 0.0f;
  r.mask[lane] = 0xffffffffu;
  r.id[lane] = static_cast<unsigned>(lane);
  r.flags[lane] = 0;
  packet.hit.geomID[lane] = RTC_INVALID_GEOMETRY_ID;
}

}  // namespace

struct RayCaster::Impl {
  DeviceErrorLog errors;  // before the device: its callback points here
  DevicePtr device;
  ScenePtr scene;
  std::vector<Surface> surfaces;

  void throwIfFailed(const char* step) const;
  void build(const World& world);
  [[nodiscard]] RayHit readHit(const RTCRayHit16& packet, int lane) const;
  [[nodiscard]] RayHit readHit(const RTCRayHit& rayhit) const;
  [[nodiscard]] RayHit makeHit(float tfar, unsigned prim, const Eigen::Vector3f& Ng,
                               const Eigen::Vector3f& dir) const;
};

void RayCaster::Impl::throwIfFailed(const char* step) const {
  const RTCError code = rtcGetDeviceError(device.get());
  if (code == RTC_ERROR_NONE && errors.message.empty()) return;
  const std::string detail =
      errors.message.empty() ? "error " + std::to_string(static_cast<int>(code)) : errors.message;
  throw core::Error(std::string("Embree failed to ") + step + ": " + detail);
}

void RayCaster::Impl::build(const World& world) {
  scene.reset(rtcNewScene(device.get()));
  throwIfFailed("create a scene");
  rtcSetSceneBuildQuality(scene.get(), kBuildQuality);
  // Without it a beam exactly along an edge shared by two triangles can slip
  // through a closed mesh; measured at no cost to trace speed.
  rtcSetSceneFlags(scene.get(), RTC_SCENE_FLAG_ROBUST);
  if (world.triangles.empty()) {
    rtcCommitScene(scene.get());
    throwIfFailed("build an empty scene");
    return;
  }
  RTCGeometry geometry = rtcNewGeometry(device.get(), RTC_GEOMETRY_TYPE_TRIANGLE);
  throwIfFailed("create the triangle geometry");
  rtcSetGeometryBuildQuality(geometry, kBuildQuality);
  // Embree's own buffers are padded for its 16-byte vector loads; the world's are not.
  void* vertices = rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                           3 * sizeof(float), world.vertices.size());
  void* indices = rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                          3 * sizeof(std::uint32_t), world.triangles.size());
  if (vertices && indices) {
    std::memcpy(vertices, world.vertices.data(), world.vertices.size() * 3 * sizeof(float));
    std::memcpy(indices, world.triangles.data(),
                world.triangles.size() * 3 * sizeof(std::uint32_t));
  }
  rtcCommitGeometry(geometry);
  rtcAttachGeometry(scene.get(), geometry);
  rtcReleaseGeometry(geometry);
  throwIfFailed("load the world's triangles");
  rtcCommitScene(scene.get());
  throwIfFailed("build the scene");
}

RayHit RayCaster::Impl::makeHit(float tfar, unsigned prim, const Eigen::Vector3f& Ng,
                                const Eigen::Vector3f& dir) const {
  RayHit hit;
  hit.range = tfar;
  hit.surface = surfaces[prim];
  const float norm = Ng.norm() * dir.norm();
  hit.cos_incidence = norm > 0.0f ? std::min(1.0f, std::abs(Ng.dot(dir)) / norm) : 0.0f;
  return hit;
}

RayHit RayCaster::Impl::readHit(const RTCRayHit16& packet, int lane) const {
  if (packet.hit.geomID[lane] == RTC_INVALID_GEOMETRY_ID) return {};
  const auto& r = packet.ray;
  const auto& h = packet.hit;
  return makeHit(r.tfar[lane], h.primID[lane], {h.Ng_x[lane], h.Ng_y[lane], h.Ng_z[lane]},
                 {r.dir_x[lane], r.dir_y[lane], r.dir_z[lane]});
}

RayHit RayCaster::Impl::readHit(const RTCRayHit& rayhit) const {
  if (rayhit.hit.geomID == RTC_INVALID_GEOMETRY_ID) return {};
  const auto& r = rayhit.ray;
  const auto& h = rayhit.hit;
  return makeHit(r.tfar, h.primID, {h.Ng_x, h.Ng_y, h.Ng_z}, {r.dir_x, r.dir_y, r.dir_z});
}

RayCaster::RayCaster(const World& world) : impl_(std::make_unique<Impl>()) {
  checkWorld(world);
  impl_->device.reset(rtcNewDevice(kDeviceConfig));
  if (!impl_->device) {
    throw core::Error("Embree could not create a device (error " +
                      std::to_string(static_cast<int>(rtcGetDeviceError(nullptr))) +
                      "): does this CPU support SSE2?");
  }
  rtcSetDeviceErrorFunction(impl_->device.get(), recordDeviceError, &impl_->errors);
  impl_->surfaces = world.surfaces;
  impl_->build(world);
}

RayCaster::~RayCaster() = default;
RayCaster::RayCaster(RayCaster&&) noexcept = default;
RayCaster& RayCaster::operator=(RayCaster&&) noexcept = default;

std::size_t RayCaster::triangleCount() const {
  return impl_->surfaces.size();
}

RayHit RayCaster::cast(const Ray& ray, float max_range) const {
  RTCRayHit rayhit{};
  rayhit.ray.org_x = ray.origin.x();
  rayhit.ray.org_y = ray.origin.y();
  rayhit.ray.org_z = ray.origin.z();
  rayhit.ray.dir_x = ray.direction.x();
  rayhit.ray.dir_y = ray.direction.y();
  rayhit.ray.dir_z = ray.direction.z();
  rayhit.ray.tnear = 0.0f;
  rayhit.ray.tfar = max_range;
  rayhit.ray.mask = 0xffffffffu;
  rayhit.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  rtcIntersect1(impl_->scene.get(), &context, &rayhit);
  return impl_->readHit(rayhit);
}

void RayCaster::cast(std::span<const Ray> rays, float max_range, std::span<RayHit> hits) const {
  if (hits.size() != rays.size()) throw core::Error("RayCaster::cast: one hit slot per ray");
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  context.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
  alignas(64) RTCRayHit16 packet;
  alignas(64) int valid[kPacket];
  for (std::size_t first = 0; first < rays.size(); first += kPacket) {
    const int count = static_cast<int>(std::min<std::size_t>(kPacket, rays.size() - first));
    for (int lane = 0; lane < kPacket; ++lane) {
      valid[lane] = lane < count ? -1 : 0;
      loadLane(packet, lane, rays[first + static_cast<std::size_t>(std::min(lane, count - 1))],
               max_range);
    }
    rtcIntersect16(valid, impl_->scene.get(), &context, &packet);
    for (int lane = 0; lane < count; ++lane)
      hits[first + static_cast<std::size_t>(lane)] = impl_->readHit(packet, lane);
  }
}

}  // namespace dcl::sim
