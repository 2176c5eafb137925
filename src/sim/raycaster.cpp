#include "raycaster.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <string>
#include <utility>
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
/// into a lost one. Pinning the kernels to SSE2 is not enough: even those
/// divide by the hardware's reciprocal estimate (`rcpps` and one Newton
/// step), whose bits differ between Intel's and AMD's CPUs, and so do the
/// distances by which Embree orders two triangles a beam meets at nearly one
/// depth (along an edge two triangles share, at the seam of a wall and the
/// ground). So Embree's distance is only a first answer: the query's filter
/// (Impl::keepNearest) goes on to every triangle the beam meets within
/// kTieWindow past the nearest of Embree's distances (Embree's tests of
/// whether a beam meets a triangle use no estimate, and give the same answer
/// everywhere), each one's distance is computed here in double precision
/// from its corners, and the nearest wins, the lower index on a tie
/// (Impl::makeHit). One query does it: a second one over the window, as this
/// caster first did, gave the same bits and took a third longer per scan
/// (`dcl-slam bench sim`, BENCHMARKS.md). A simulated dataset is then the same bits on
/// every x86-64 CPU (`ctest -R ScanChecksums`, which also runs the scans on
/// an emulated CPU and with glibc's AVX2 and FMA paths switched off). SSE2
/// stays: the tests of whether a beam meets a triangle are then one code
/// path everywhere, without the fused multiply-adds of AVX2.
constexpr const char* kDeviceConfig = "isa=sse2";

/// The window past Embree's nearest distance: its estimate is off
/// by a few units in the last place of a float (1e-7 of the range), so
/// every triangle that could be nearer is within it, and none that is
/// farther by more than a millimetre in 100 m can win.
constexpr float kTieWindowRelative = 1e-5f;
constexpr float kTieWindowAbsolute = 1e-5f;  ///< m

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
  std::vector<Eigen::Vector3f> vertices;                ///< the world's, for the exact range
  std::vector<std::array<std::uint32_t, 3>> triangles;  ///< the world's

  /// The query's state: for each lane of a packet, the nearest triangle met
  /// so far by its exact range.
  struct TieContext {
    RTCIntersectContext context;  ///< first: Embree hands the filter a pointer to it
    const Impl* impl = nullptr;
    std::array<double, kPacket> range{};
    std::array<unsigned, kPacket> prim{};
    std::array<float, kPacket> far{};  ///< the window's end past the nearest of Embree's distances
    std::array<Eigen::Vector3d, kPacket> origin{};  ///< the beams'
    std::array<Eigen::Vector3d, kPacket> dir{};
  };

  void throwIfFailed(const char* step) const;
  void build(const World& world);
  [[nodiscard]] std::pair<Eigen::Vector3d, Eigen::Vector3d> cornerAndNormal(unsigned prim) const;
  [[nodiscard]] double exactRange(unsigned prim, const Eigen::Vector3d& origin,
                                  const Eigen::Vector3d& dir) const;
  [[nodiscard]] RayHit makeHit(unsigned prim, double range, const Eigen::Vector3d& dir) const;
  void castPacket(RTCRayHit16& packet, const int* valid, std::span<RayHit> hits) const;
  static void keepNearest(const RTCFilterFunctionNArguments* args);
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
  // Without ROBUST a beam exactly along an edge shared by two triangles can
  // slip through a closed mesh (measured at no cost to trace speed); the
  // context's filter weighs the triangles near the nearest (Impl::keepNearest).
  rtcSetSceneFlags(scene.get(), static_cast<RTCSceneFlags>(RTC_SCENE_FLAG_ROBUST |
                                                           RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION));
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

/// Triangle `prim`'s first corner and its (unnormalised) normal, in double precision.
std::pair<Eigen::Vector3d, Eigen::Vector3d> RayCaster::Impl::cornerAndNormal(unsigned prim) const {
  const auto& t = triangles[prim];
  const Eigen::Vector3d a = vertices[t[0]].cast<double>();
  return {a, (vertices[t[1]].cast<double>() - a).cross(vertices[t[2]].cast<double>() - a)};
}

/// The range from `origin` along `dir` to the plane of triangle `prim`, in
/// double precision from its corners (IEEE operations only: the same bits on
/// every CPU); NaN for a beam along the plane or a triangle without one.
double RayCaster::Impl::exactRange(unsigned prim, const Eigen::Vector3d& origin,
                                   const Eigen::Vector3d& dir) const {
  const auto [a, n] = cornerAndNormal(prim);
  const double along = n.dot(dir);
  if (along == 0.0) return std::numeric_limits<double>::quiet_NaN();
  return n.dot(a - origin) / along;
}

/// The hit on triangle `prim` at `range`, rounded once to float, and the
/// angle between the beam and the triangle's normal.
RayHit RayCaster::Impl::makeHit(unsigned prim, double range, const Eigen::Vector3d& dir) const {
  const Eigen::Vector3d n = cornerAndNormal(prim).second;
  const double scale = n.norm() * dir.norm();
  RayHit hit;
  hit.range = static_cast<float>(range);
  hit.surface = surfaces[prim];
  hit.cos_incidence =
      scale > 0.0 ? static_cast<float>(std::min(1.0, std::abs(n.dot(dir)) / scale)) : 0.0f;
  return hit;
}

/// The query's filter. Every triangle the beam meets is weighed by its exact
/// range, and the hit is accepted with the beam's far end moved to the
/// window's end past the nearest of Embree's distances met so far (Embree
/// lets a filter move it), not to the hit: Embree then goes on to every
/// triangle within the window of the nearest, whatever order it meets them
/// in, and to none much farther.
void RayCaster::Impl::keepNearest(const RTCFilterFunctionNArguments* args) {
  auto* tie = reinterpret_cast<TieContext*>(args->context);
  for (unsigned i = 0; i < args->N; ++i) {
    if (args->valid[i] != -1) continue;
    const unsigned lane = RTCRayN_id(args->ray, args->N, i);
    if (lane >= static_cast<unsigned>(kPacket)) {
      args->valid[i] = 0;
      continue;
    }
    float& tfar = RTCRayN_tfar(args->ray, args->N, i);  // Embree's distance to this triangle
    const float window = tfar * kTieWindowRelative + kTieWindowAbsolute;
    tie->far[lane] = std::min(tie->far[lane], tfar + window);
    tfar = tie->far[lane];
    const unsigned prim = RTCHitN_primID(args->hit, args->N, i);
    const double range = tie->impl->exactRange(prim, tie->origin[lane], tie->dir[lane]);
    if (!(range >= 0.0)) continue;
    if (range < tie->range[lane] || (range == tie->range[lane] && prim < tie->prim[lane])) {
      tie->range[lane] = range;
      tie->prim[lane] = prim;
    }
  }
}

/// One packet's query (its valid lanes `valid`, their hits into `hits`).
void RayCaster::Impl::castPacket(RTCRayHit16& packet, const int* valid,
                                 std::span<RayHit> hits) const {
  TieContext tie;
  rtcInitIntersectContext(&tie.context);
  tie.context.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
  tie.context.filter = keepNearest;
  tie.impl = this;
  tie.range.fill(std::numeric_limits<double>::infinity());
  auto& r = packet.ray;
  for (int lane = 0; lane < kPacket; ++lane) {
    tie.far[lane] = r.tfar[lane];
    tie.origin[lane] = {r.org_x[lane], r.org_y[lane], r.org_z[lane]};
    tie.dir[lane] = {r.dir_x[lane], r.dir_y[lane], r.dir_z[lane]};
  }
  rtcIntersect16(valid, scene.get(), &tie.context, &packet);
  for (std::size_t lane = 0; lane < hits.size(); ++lane) {
    hits[lane] = std::isfinite(tie.range[lane])
                     ? makeHit(tie.prim[lane], tie.range[lane], tie.dir[lane])
                     : RayHit{};
  }
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
  impl_->vertices = world.vertices;
  impl_->triangles = world.triangles;
  impl_->build(world);
}

RayCaster::~RayCaster() = default;
RayCaster::RayCaster(RayCaster&&) noexcept = default;
RayCaster& RayCaster::operator=(RayCaster&&) noexcept = default;

std::size_t RayCaster::triangleCount() const {
  return impl_->surfaces.size();
}

RayHit RayCaster::cast(const Ray& ray, float max_range) const {
  RayHit hit;
  cast(std::span<const Ray>(&ray, 1), max_range, std::span<RayHit>(&hit, 1));
  return hit;
}

void RayCaster::cast(std::span<const Ray> rays, float max_range, std::span<RayHit> hits) const {
  if (hits.size() != rays.size()) throw core::Error("RayCaster::cast: one hit slot per ray");
  alignas(64) RTCRayHit16 packet;
  alignas(64) int valid[kPacket];
  for (std::size_t first = 0; first < rays.size(); first += kPacket) {
    const int count = static_cast<int>(std::min<std::size_t>(kPacket, rays.size() - first));
    for (int lane = 0; lane < kPacket; ++lane) {
      valid[lane] = lane < count ? -1 : 0;
      loadLane(packet, lane, rays[first + static_cast<std::size_t>(std::min(lane, count - 1))],
               max_range);
    }
    impl_->castPacket(packet, valid, hits.subspan(first, static_cast<std::size_t>(count)));
  }
}

}  // namespace dcl::sim
