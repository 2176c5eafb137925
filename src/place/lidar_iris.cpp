#include <kiss_fftr.h>

#include <dcl/core/config.hpp>
#include <dcl/place/lidar_iris.hpp>

#if defined(__SSE2__)
#include <immintrin.h>
#endif

#include <algorithm>
#include <bit>
#include <cmath>
#include <string>

#include <dcl/core/error.hpp>

namespace dcl::place {

namespace {

constexpr float kPiF = 3.14159265358979323846F;

void check(bool ok, const std::string& what) {
  if (!ok) throw core::Error("LiDAR-Iris: " + what);
}

std::size_t idx(int i) {
  return static_cast<std::size_t>(i);
}

/// atan(lo / hi) for 0 <= lo <= hi, hi > 0, absolute error below 1e-7 rad:
/// one reduction by tan(pi/8) and the classic odd polynomial (Cephes'
/// atanf). The image needs an angle for each of ~120 k points a scan; libm's
/// atan2f alone would use the whole description budget. The reduction
/// (a - 1) / (a + 1) with a = lo / hi is taken as (lo - hi) / (lo + hi): one
/// division a point instead of two.
inline float atanRatio(float lo, float hi) {
  const bool big = lo > 0.41421356F * hi;
  const float t = (big ? lo - hi : lo) / (big ? lo + hi : hi);
  const float z = t * t;
  const float p = (((8.05374449538e-2F * z - 1.38776856032e-1F) * z + 1.99777106478e-1F) * z -
                   3.33329491539e-1F) *
                      z * t +
                  t;
  return big ? p + 0.25F * kPiF : p;
}

/// The column of the direction (x, y): the nearest multiple of 360/columns
/// degrees, counter-clockwise from +x (the original's floor(yaw + 0.5)).
/// Selects rather than branches, so that a loop over points vectorises.
inline int columnOf(float x, float y, int columns) {
  const float ax = __builtin_fabsf(x);
  const float ay = __builtin_fabsf(y);
  const float hi = ax > ay ? ax : ay;
  const float lo = ax > ay ? ay : ax;
  float r = atanRatio(lo, hi > 1e-30F ? hi : 1e-30F);
  r = ay > ax ? 0.5F * kPiF - r : r;
  r = x < 0.0F ? kPiF - r : r;
  r = y < 0.0F ? 2.0F * kPiF - r : r;  // [0, 2 pi)
  const int c = static_cast<int>(r * (static_cast<float>(columns) / (2.0F * kPiF)) + 0.5F);
  return c >= columns ? c - columns : c;
}

/// Everything the per-point loop needs, in float.
struct ImageGrid {
  float row_scale = 1.0F;  // rows per metre
  float lowest = -5.0F;
  float inv_slab = 1.0F;
  int rows = 80;
  int columns = 360;
};

#if defined(__SSE2__)

inline __m128 select(__m128 mask, __m128 a, __m128 b) {
  return _mm_or_ps(_mm_and_ps(mask, a), _mm_andnot_ps(mask, b));
}

/// atanRatio on four lanes, the same operations in the same order, so that
/// the bins match the scalar path bit for bit.
inline __m128 atanRatio4(__m128 lo, __m128 hi) {
  const __m128 big = _mm_cmpgt_ps(lo, _mm_mul_ps(_mm_set1_ps(0.41421356F), hi));
  const __m128 t =
      _mm_div_ps(select(big, _mm_sub_ps(lo, hi), lo), select(big, _mm_add_ps(lo, hi), hi));
  const __m128 z = _mm_mul_ps(t, t);
  __m128 p =
      _mm_sub_ps(_mm_mul_ps(_mm_set1_ps(8.05374449538e-2F), z), _mm_set1_ps(1.38776856032e-1F));
  p = _mm_add_ps(_mm_mul_ps(p, z), _mm_set1_ps(1.99777106478e-1F));
  p = _mm_sub_ps(_mm_mul_ps(p, z), _mm_set1_ps(3.33329491539e-1F));
  p = _mm_add_ps(_mm_mul_ps(_mm_mul_ps(p, z), t), t);
  return select(big, _mm_add_ps(p, _mm_set1_ps(0.25F * kPiF)), p);
}

/// columnOf on four lanes (same operations, same bins).
inline __m128i columnOf4(__m128 x, __m128 y, int columns) {
  const __m128 zero = _mm_setzero_ps();
  const __m128 sign = _mm_set1_ps(-0.0F);
  const __m128 ax = _mm_andnot_ps(sign, x);
  const __m128 ay = _mm_andnot_ps(sign, y);
  // max/min pick the same values as the scalar selects: no lane is NaN.
  const __m128 hi = _mm_max_ps(ax, ay);
  const __m128 lo = _mm_min_ps(ax, ay);
  __m128 r = atanRatio4(lo, _mm_max_ps(hi, _mm_set1_ps(1e-30F)));
  r = select(_mm_cmpgt_ps(ay, ax), _mm_sub_ps(_mm_set1_ps(0.5F * kPiF), r), r);
  r = select(_mm_cmplt_ps(x, zero), _mm_sub_ps(_mm_set1_ps(kPiF), r), r);
  r = select(_mm_cmplt_ps(y, zero), _mm_sub_ps(_mm_set1_ps(2.0F * kPiF), r), r);
  const __m128 scale = _mm_set1_ps(static_cast<float>(columns) / (2.0F * kPiF));
  const __m128i c = _mm_cvttps_epi32(_mm_add_ps(_mm_mul_ps(r, scale), _mm_set1_ps(0.5F)));
  const __m128i wrap = _mm_cmpgt_epi32(c, _mm_set1_epi32(columns - 1));
  return _mm_sub_epi32(c, _mm_and_si128(wrap, _mm_set1_epi32(columns)));
}

/// x, y and z of four packed points: the 12 floats x0 y0 z0 x1 | y1 z1 x2 y2
/// | z2 x3 y3 z3 split by shuffles, fewer instructions than four scalar loads
/// a coordinate.
inline void splitFour(const float* f, __m128& x, __m128& y, __m128& z) {
  const __m128 a0 = _mm_loadu_ps(f), a1 = _mm_loadu_ps(f + 4), a2 = _mm_loadu_ps(f + 8);
  const __m128 x1y1 = _mm_shuffle_ps(a0, a1, _MM_SHUFFLE(0, 0, 3, 3));
  const __m128 xy01 = _mm_shuffle_ps(a0, x1y1, _MM_SHUFFLE(2, 0, 1, 0));
  const __m128 xy23 = _mm_shuffle_ps(a1, a2, _MM_SHUFFLE(2, 1, 3, 2));
  const __m128 z01 = _mm_shuffle_ps(a0, a1, _MM_SHUFFLE(1, 1, 2, 2));
  const __m128 z23 = _mm_shuffle_ps(a2, a2, _MM_SHUFFLE(3, 3, 0, 0));
  x = _mm_shuffle_ps(xy01, xy23, _MM_SHUFFLE(2, 0, 2, 0));
  y = _mm_shuffle_ps(xy01, xy23, _MM_SHUFFLE(3, 1, 3, 1));
  z = _mm_shuffle_ps(z01, z23, _MM_SHUFFLE(2, 0, 2, 0));
}

/// Bins four points: the cell index of each, and its height slab, 8 (a bit
/// that a uint8_t cell does not hold) for a point that is not finite.
/// Intrinsics rather than a loop for the vectoriser, which GCC refuses (it
/// sees control flow in the selects); about twice as fast as that loop.
inline void binFour(const ImageGrid& g, const Eigen::Vector3f* p, int* cell, int* slab) {
  static_assert(sizeof(Eigen::Vector3f) == 3 * sizeof(float), "points are packed xyz");
  __m128 x, y, z;
  splitFour(p[0].data(), x, y, z);
  const __m128 zero = _mm_setzero_ps();
  const __m128 finite = _mm_and_ps(
      _mm_and_ps(_mm_cmpeq_ps(_mm_sub_ps(x, x), zero), _mm_cmpeq_ps(_mm_sub_ps(y, y), zero)),
      _mm_cmpeq_ps(_mm_sub_ps(z, z), zero));
  const __m128 range = _mm_sqrt_ps(_mm_add_ps(_mm_mul_ps(x, x), _mm_mul_ps(y, y)));
  const __m128 row_f = _mm_min_ps(_mm_and_ps(finite, _mm_mul_ps(range, _mm_set1_ps(g.row_scale))),
                                  _mm_set1_ps(static_cast<float>(g.rows - 1)));
  const __m128i row = _mm_cvttps_epi32(row_f);
  // clamp(ceil(v), 0, 7) as ceil(clamp(v, -0.5, 7)): the same slab, with
  // the clamp in float. ceil by hand: SSE2 has no rounding instruction.
  const __m128 h =
      _mm_and_ps(finite, _mm_mul_ps(_mm_sub_ps(z, _mm_set1_ps(g.lowest)), _mm_set1_ps(g.inv_slab)));
  const __m128 v = _mm_min_ps(_mm_max_ps(h, _mm_set1_ps(-0.5F)), _mm_set1_ps(7.0F));
  const __m128i t = _mm_cvttps_epi32(v);
  const __m128i s = _mm_sub_epi32(t, _mm_castps_si128(_mm_cmplt_ps(_mm_cvtepi32_ps(t), v)));
  const __m128i fin = _mm_castps_si128(finite);
  _mm_storeu_si128(reinterpret_cast<__m128i*>(slab),
                   _mm_or_si128(_mm_and_si128(fin, s), _mm_andnot_si128(fin, _mm_set1_epi32(8))));
  const __m128i column =
      columnOf4(select(finite, x, _mm_set1_ps(1.0F)), select(finite, y, zero), g.columns);
  // row * columns in float (exact for these small integers): SSE2 has no
  // 32-bit integer multiply.
  const __m128i row_start = _mm_cvttps_epi32(
      _mm_mul_ps(_mm_cvtepi32_ps(row), _mm_set1_ps(static_cast<float>(g.columns))));
  _mm_storeu_si128(reinterpret_cast<__m128i*>(cell), _mm_add_epi32(row_start, column));
}

#if defined(__x86_64__) && defined(__GNUC__)
#define DCL_IRIS_AVX2 1

// The same binning on eight lanes, compiled for AVX2 (without FMA, which
// would round differently from the scalar path) and chosen at run time.
#define DCL_AVX2 __attribute__((target("avx2")))

DCL_AVX2 inline __m256 select8(__m256 mask, __m256 a, __m256 b) {
  return _mm256_blendv_ps(b, a, mask);
}

DCL_AVX2 inline __m256 atanRatio8(__m256 lo, __m256 hi) {
  const __m256 big = _mm256_cmp_ps(lo, _mm256_mul_ps(_mm256_set1_ps(0.41421356F), hi), _CMP_GT_OQ);
  const __m256 t = _mm256_div_ps(select8(big, _mm256_sub_ps(lo, hi), lo),
                                 select8(big, _mm256_add_ps(lo, hi), hi));
  const __m256 z = _mm256_mul_ps(t, t);
  __m256 p = _mm256_sub_ps(_mm256_mul_ps(_mm256_set1_ps(8.05374449538e-2F), z),
                           _mm256_set1_ps(1.38776856032e-1F));
  p = _mm256_add_ps(_mm256_mul_ps(p, z), _mm256_set1_ps(1.99777106478e-1F));
  p = _mm256_sub_ps(_mm256_mul_ps(p, z), _mm256_set1_ps(3.33329491539e-1F));
  p = _mm256_add_ps(_mm256_mul_ps(_mm256_mul_ps(p, z), t), t);
  return select8(big, _mm256_add_ps(p, _mm256_set1_ps(0.25F * kPiF)), p);
}

DCL_AVX2 inline __m256i columnOf8(__m256 x, __m256 y, int columns) {
  const __m256 zero = _mm256_setzero_ps();
  const __m256 sign = _mm256_set1_ps(-0.0F);
  const __m256 ax = _mm256_andnot_ps(sign, x);
  const __m256 ay = _mm256_andnot_ps(sign, y);
  const __m256 hi = _mm256_max_ps(ax, ay);
  const __m256 lo = _mm256_min_ps(ax, ay);
  __m256 r = atanRatio8(lo, _mm256_max_ps(hi, _mm256_set1_ps(1e-30F)));
  r = select8(_mm256_cmp_ps(ay, ax, _CMP_GT_OQ), _mm256_sub_ps(_mm256_set1_ps(0.5F * kPiF), r), r);
  r = select8(_mm256_cmp_ps(x, zero, _CMP_LT_OQ), _mm256_sub_ps(_mm256_set1_ps(kPiF), r), r);
  r = select8(_mm256_cmp_ps(y, zero, _CMP_LT_OQ), _mm256_sub_ps(_mm256_set1_ps(2.0F * kPiF), r), r);
  const __m256 scale = _mm256_set1_ps(static_cast<float>(columns) / (2.0F * kPiF));
  const __m256i c =
      _mm256_cvttps_epi32(_mm256_add_ps(_mm256_mul_ps(r, scale), _mm256_set1_ps(0.5F)));
  const __m256i wrap = _mm256_cmpgt_epi32(c, _mm256_set1_epi32(columns - 1));
  return _mm256_sub_epi32(c, _mm256_and_si256(wrap, _mm256_set1_epi32(columns)));
}

/// binFour on eight points.
DCL_AVX2 inline void binEight(const ImageGrid& g, const Eigen::Vector3f* p, int* cell, int* slab) {
  __m128 x0, y0, z0, x1, y1, z1;
  splitFour(p[0].data(), x0, y0, z0);
  splitFour(p[4].data(), x1, y1, z1);
  const __m256 x = _mm256_set_m128(x1, x0);
  const __m256 y = _mm256_set_m128(y1, y0);
  const __m256 z = _mm256_set_m128(z1, z0);
  const __m256 zero = _mm256_setzero_ps();
  const __m256 finite =
      _mm256_and_ps(_mm256_and_ps(_mm256_cmp_ps(_mm256_sub_ps(x, x), zero, _CMP_EQ_OQ),
                                  _mm256_cmp_ps(_mm256_sub_ps(y, y), zero, _CMP_EQ_OQ)),
                    _mm256_cmp_ps(_mm256_sub_ps(z, z), zero, _CMP_EQ_OQ));
  const __m256 range = _mm256_sqrt_ps(_mm256_add_ps(_mm256_mul_ps(x, x), _mm256_mul_ps(y, y)));
  const __m256 row_f =
      _mm256_min_ps(_mm256_and_ps(finite, _mm256_mul_ps(range, _mm256_set1_ps(g.row_scale))),
                    _mm256_set1_ps(static_cast<float>(g.rows - 1)));
  const __m256i row = _mm256_cvttps_epi32(row_f);
  const __m256 h = _mm256_and_ps(finite, _mm256_mul_ps(_mm256_sub_ps(z, _mm256_set1_ps(g.lowest)),
                                                       _mm256_set1_ps(g.inv_slab)));
  const __m256 v = _mm256_min_ps(_mm256_max_ps(h, _mm256_set1_ps(-0.5F)), _mm256_set1_ps(7.0F));
  const __m256i s = _mm256_cvttps_epi32(_mm256_ceil_ps(v));
  const __m256i fin = _mm256_castps_si256(finite);
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(slab),
                      _mm256_blendv_epi8(_mm256_set1_epi32(8), s, fin));
  const __m256i column =
      columnOf8(select8(finite, x, _mm256_set1_ps(1.0F)), select8(finite, y, zero), g.columns);
  const __m256i row_start = _mm256_mullo_epi32(row, _mm256_set1_epi32(g.columns));
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(cell), _mm256_add_epi32(row_start, column));
}

DCL_AVX2 int binChunkAvx2(const ImageGrid& g, const Eigen::Vector3f* points, int count, int* cell,
                          int* slab) {
  int i = 0;
  for (; i + 8 <= count; i += 8) binEight(g, points + i, cell + i, slab + i);
  return i;
}

bool hasAvx2() {
  static const bool has = __builtin_cpu_supports("avx2");
  return has;
}

#undef DCL_AVX2
#endif
#endif

/// Bins one point as binFour does: its cell index and slab (8 if not finite).
inline void binOne(const ImageGrid& g, const Eigen::Vector3f& p, int* cell, int* slab) {
  const float x = p.x(), y = p.y(), z = p.z();
  const bool finite = std::isfinite(x) && std::isfinite(y) && std::isfinite(z);
  const float range = std::sqrt(x * x + y * y);
  const int row = static_cast<int>(
      std::min(finite ? range * g.row_scale : 0.0F, static_cast<float>(g.rows - 1)));
  // The slab index ceil((z - lowest) / slab), clamped to the 8 bits of a
  // cell: for KITTI's HDL-64, bit clamp(ceil(z + 5), 0, 7).
  const float v = std::clamp(finite ? (z - g.lowest) * g.inv_slab : 0.0F, -1.0F, 8.0F);
  *slab = finite ? std::clamp(static_cast<int>(std::ceil(v)), 0, 7) : 8;
  *cell = row * g.columns + columnOf(finite ? x : 1.0F, finite ? y : 0.0F, g.columns);
}

/// Bins a chunk of points: the cell index of each, and its height slab.
void binChunk(const ImageGrid& g, const Eigen::Vector3f* points, int count, int* cell, int* slab) {
  int i = 0;
#if defined(DCL_IRIS_AVX2)
  if (hasAvx2()) i = binChunkAvx2(g, points, count, cell, slab);
#endif
#if defined(__SSE2__)
  for (; i + 4 <= count; i += 4) binFour(g, points + i, cell + i, slab + i);
#endif
  for (; i < count; ++i) binOne(g, points[i], cell + i, slab + i);
}

/// A kissfft real-to-complex or complex-to-real plan, freed with the object.
struct RealPlan {
  kiss_fftr_cfg cfg = nullptr;
  int n = 0;
  RealPlan(int size, bool inverse)
      : cfg(kiss_fftr_alloc(size, inverse ? 1 : 0, nullptr, nullptr)), n(size) {}
  ~RealPlan() { kiss_fftr_free(cfg); }
  RealPlan(const RealPlan&) = delete;
  RealPlan& operator=(const RealPlan&) = delete;
};

/// One inverse real FFT plan per thread and length: plans keep scratch
/// buffers, and making one costs more than the transform.
RealPlan& inversePlan(int n) {
  thread_local std::unique_ptr<RealPlan> plan;
  if (!plan || plan->n != n) plan = std::make_unique<RealPlan>(n, true);
  return *plan;
}

bool sameFilters(const LogGaborConfig& a, const LogGaborConfig& b) {
  return a.scales == b.scales && a.min_wavelength == b.min_wavelength &&
         a.multiplier == b.multiplier && a.sigma_on_f == b.sigma_on_f;
}

/// One filter bank per thread (see LogGaborBank: not shareable).
LogGaborBank& bankFor(int columns, const LogGaborConfig& config) {
  thread_local std::unique_ptr<LogGaborBank> bank;
  if (!bank || bank->columns() != columns || !sameFilters(bank->config(), config))
    bank = std::make_unique<LogGaborBank>(columns, config);
  return *bank;
}

void setBit(std::uint64_t* row, int column) {
  row[column / 64] |= std::uint64_t{1} << (column % 64);
}

/// Scratch for describing one image.
struct FeatureScratch {
  std::vector<float> row;
  std::vector<std::complex<float>> spectrum;
  std::vector<std::complex<float>> response;
};

/// Feature and mask bits of one response value, at bit `b`.
inline void packOne(std::complex<float> v, float threshold2, int b, std::uint64_t& re,
                    std::uint64_t& im, std::uint64_t& mask) {
  re |= static_cast<std::uint64_t>(v.real() > 0.0F) << b;
  im |= static_cast<std::uint64_t>(v.imag() > 0.0F) << b;
  mask |= static_cast<std::uint64_t>(std::norm(v) < threshold2) << b;
}

#if defined(__SSE2__)
/// packOne for the four values at `v`, at bits b..b+3: movemask turns four
/// comparisons into four bits at once (the scalar loop does not vectorise).
inline void packFour(const std::complex<float>* v, __m128 threshold2, int b, std::uint64_t& re,
                     std::uint64_t& im, std::uint64_t& mask) {
  const __m128 lo = _mm_loadu_ps(reinterpret_cast<const float*>(v));
  const __m128 hi = _mm_loadu_ps(reinterpret_cast<const float*>(v + 2));
  const __m128 r = _mm_shuffle_ps(lo, hi, _MM_SHUFFLE(2, 0, 2, 0));
  const __m128 i = _mm_shuffle_ps(lo, hi, _MM_SHUFFLE(3, 1, 3, 1));
  const __m128 zero = _mm_setzero_ps();
  // x * x + y * y, as std::norm computes it.
  const __m128 norm = _mm_add_ps(_mm_mul_ps(r, r), _mm_mul_ps(i, i));
  re |= static_cast<std::uint64_t>(_mm_movemask_ps(_mm_cmpgt_ps(r, zero))) << b;
  im |= static_cast<std::uint64_t>(_mm_movemask_ps(_mm_cmpgt_ps(i, zero))) << b;
  mask |= static_cast<std::uint64_t>(_mm_movemask_ps(_mm_cmplt_ps(norm, threshold2))) << b;
}
#endif

/// Feature and mask bits of one row at one scale, from its complex response,
/// built a word at a time without branches.
void packResponse(const std::vector<std::complex<float>>& response, float threshold,
                  std::uint64_t* re, std::uint64_t* im, std::uint64_t* mask) {
  const float threshold2 = threshold * threshold;
  const int n = static_cast<int>(response.size());
  for (int w = 0; w * 64 < n; ++w) {
    std::uint64_t r = 0, i = 0, m = 0;
    const int end = std::min(64, n - w * 64);
    const std::complex<float>* v = response.data() + w * 64;
    int b = 0;
#if defined(__SSE2__)
    for (; b + 4 <= end; b += 4) packFour(v + b, _mm_set1_ps(threshold2), b, r, i, m);
#endif
    for (; b < end; ++b) packOne(v[b], threshold2, b, r, i, m);
    re[w] = r;
    im[w] = i;
    mask[w] = m;
  }
}

/// Word offset of (plane, row) in a packed array.
std::size_t rowOffset(const IrisDescriptor& d, int plane, int row) {
  return (idx(plane) * idx(d.image.rows) + idx(row)) * idx(d.words);
}

/// Masks every column of an empty row (no response at all, as the original's
/// magnitude test gives).
void maskWholeRow(IrisDescriptor& d, int row) {
  for (int s = 0; s < d.scales; ++s)
    for (int c = 0; c < d.image.columns; ++c) setBit(&d.mask[rowOffset(d, s, row)], c);
}

/// The LoG-Gabor features of one image row (Eq. 2), and its spectrum added
/// to its band for the phase correlation (Eq. 3-4).
void describeRow(IrisDescriptor& d, const IrisConfig& config, int row, LogGaborBank& bank,
                 FeatureScratch& scratch) {
  const std::span<const std::uint8_t> codes = d.image.row(row);
  if (std::all_of(codes.begin(), codes.end(), [](std::uint8_t c) { return c == 0; }))
    return maskWholeRow(d, row);
  std::transform(codes.begin(), codes.end(), scratch.row.begin(),
                 [](std::uint8_t c) { return static_cast<float>(c); });
  bank.spectrum(scratch.row, scratch.spectrum);
  const std::size_t bins = scratch.spectrum.size();
  const int band = row * config.shift_bands / d.image.rows;
  for (std::size_t k = 0; k < bins; ++k)
    d.band_spectra[idx(band) * bins + k] += scratch.spectrum[k];
  const auto threshold = static_cast<float>(config.log_gabor.mask_threshold);
  for (int s = 0; s < d.scales; ++s) {
    bank.response(scratch.spectrum, s, scratch.response);
    packResponse(scratch.response, threshold, &d.features[rowOffset(d, s, row)],
                 &d.features[rowOffset(d, s + d.scales, row)], &d.mask[rowOffset(d, s, row)]);
  }
}

void checkComparable(const IrisDescriptor& a, const IrisDescriptor& b) {
  check(a.image.rows == b.image.rows && a.image.columns == b.image.columns &&
            a.scales == b.scales && a.words == b.words &&
            a.band_spectra.size() == b.band_spectra.size() && a.image.columns > 0,
        "cannot compare descriptors of different dimensions");
}

}  // namespace

void validate(const IrisConfig& config) {
  core::checkConfig(config, "LiDAR-Iris config");
}

std::span<const std::uint64_t> IrisDescriptor::featureRow(int plane, int row) const {
  return {features.data() + rowOffset(*this, plane, row), idx(words)};
}

std::span<const std::uint64_t> IrisDescriptor::maskRow(int scale, int row) const {
  return {mask.data() + rowOffset(*this, scale, row), idx(words)};
}

IrisImage makeIrisImage(const core::PointCloud& scan, const IrisConfig& config) {
  const HeightEncoding h = config.heightEncoding();
  const ImageGrid grid{static_cast<float>(config.rows / config.max_range),
                       static_cast<float>(h.lowest), static_cast<float>(1.0 / h.slab), config.rows,
                       config.columns};
  IrisImage image{config.rows, config.columns,
                  std::vector<std::uint8_t>(idx(config.rows * config.columns), 0)};
  constexpr int kChunk = 512;
  int cell[kChunk];
  int slab[kChunk];
  const int total = static_cast<int>(scan.points.size());
  for (int start = 0; start < total; start += kChunk) {
    const int count = std::min(kChunk, total - start);
    binChunk(grid, scan.points.data() + start, count, cell, slab);
    // Slab 8 (a non-finite point) sets a bit the uint8_t cell drops.
    for (int i = 0; i < count; ++i)
      image.cells[idx(cell[i])] |= static_cast<std::uint8_t>(1U << slab[i]);
  }
  return image;
}

std::vector<float> irisRowKey(const IrisImage& image) {
  std::vector<float> key(idx(image.rows), 0.0F);
  for (int r = 0; r < image.rows; ++r) {
    double sum = 0.0;
    for (std::uint8_t c : image.row(r)) sum += static_cast<double>(c) * c;
    key[idx(r)] = static_cast<float>(std::sqrt(sum));
  }
  return key;
}

IrisDescriptor describeIrisImage(IrisImage image, const IrisConfig& config) {
  check(image.rows == config.rows && image.columns == config.columns &&
            image.cells.size() == idx(image.rows) * idx(image.columns),
        "image dimensions do not match the configuration");
  IrisDescriptor d;
  d.image = std::move(image);
  d.row_key = irisRowKey(d.image);
  d.scales = config.log_gabor.scales;
  d.words = (config.columns + 63) / 64;
  d.features.assign(idx(2 * d.scales * config.rows * d.words), 0);
  d.mask.assign(idx(d.scales * config.rows * d.words), 0);
  const int bins = config.columns / 2 + 1;
  d.band_spectra.assign(idx(config.shift_bands * bins), {0.0F, 0.0F});
  LogGaborBank& bank = bankFor(config.columns, config.log_gabor);
  FeatureScratch scratch{std::vector<float>(idx(config.columns)),
                         std::vector<std::complex<float>>(idx(bins)),
                         std::vector<std::complex<float>>(idx(config.columns))};
  for (int r = 0; r < config.rows; ++r) describeRow(d, config, r, bank, scratch);
  return d;
}

IrisDescriptor describeIris(const core::PointCloud& scan, const IrisConfig& config) {
  return describeIrisImage(makeIrisImage(scan, config), config);
}

std::vector<float> irisShiftCorrelation(const IrisDescriptor& query,
                                        const IrisDescriptor& candidate) {
  checkComparable(query, candidate);
  const int n = query.image.columns;
  const std::size_t bins = idx(n / 2 + 1);
  const std::size_t bands = query.band_spectra.size() / bins;
  // Eq. 3-4: a rotation by s columns multiplies each bin k of the candidate's
  // spectrum by exp(-2 pi i k s / n); whitening the cross-power spectrum summed
  // over the bands leaves that phase alone, whose inverse DFT peaks at s. Bin 0
  // (the mean) carries no shift.
  std::vector<std::complex<float>> cross(bins, {0.0F, 0.0F});
  for (std::size_t b = 0; b < bands; ++b)
    for (std::size_t k = 1; k < bins; ++k)
      cross[k] +=
          candidate.band_spectra[b * bins + k] * std::conj(query.band_spectra[b * bins + k]);
  for (std::complex<float>& c : cross) {
    const float m = std::abs(c);
    c = m > 1e-12F ? c / m : std::complex<float>{0.0F, 0.0F};
  }
  std::vector<float> correlation(idx(n));
  kiss_fftri(inversePlan(n).cfg, reinterpret_cast<const kiss_fft_cpx*>(cross.data()),
             correlation.data());
  return correlation;
}

namespace {

/// The query's packed rows, each written twice in a row (2n bits, plus a spare
/// word), so that any circular shift of a row is a contiguous bit window.
struct DoubledRows {
  int stride = 0;  // words a doubled row
  std::vector<std::uint64_t> bits;
};

/// ORs the `words` words of `src` into `dst` starting at bit `offset`.
void orAt(std::uint64_t* dst, const std::uint64_t* src, int words, int offset) {
  const int w0 = offset / 64;
  const int b = offset % 64;
  for (int w = 0; w < words; ++w) {
    dst[w0 + w] |= src[w] << b;
    if (b != 0) dst[w0 + w + 1] |= src[w] >> (64 - b);
  }
}

DoubledRows doubleRows(const std::vector<std::uint64_t>& packed, int words, int columns) {
  const std::size_t count = packed.size() / idx(words);
  DoubledRows d{2 * words + 1, {}};
  d.bits.assign(count * idx(d.stride), 0);
  for (std::size_t r = 0; r < count; ++r) {
    std::uint64_t* dst = d.bits.data() + r * idx(d.stride);
    orAt(dst, packed.data() + r * idx(words), words, 0);
    orAt(dst, packed.data() + r * idx(words), words, columns);
  }
  return d;
}

/// Word `w` of the window of `columns` bits that starts at bit `offset`.
inline std::uint64_t window(const std::uint64_t* doubled, int offset, int w) {
  const int w0 = offset / 64 + w;
  const int b = offset % 64;
  return b == 0 ? doubled[w0] : (doubled[w0] >> b) | (doubled[w0 + 1] << (64 - b));
}

/// What Eq. 6 counts: differing bits and bits masked in neither.
struct BitCounts {
  std::uint64_t differing = 0;
  std::uint64_t valid = 0;
};

/// Counts for one (scale, row) at one window offset of the query. Compiled
/// for the popcnt instruction where the CPU has it (x86-64's baseline lacks it).
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
__attribute__((target_clones("popcnt", "default")))
#endif
BitCounts
countRow(const std::uint64_t* q_re, const std::uint64_t* q_im, const std::uint64_t* q_mask,
         const std::uint64_t* c_re, const std::uint64_t* c_im, const std::uint64_t* c_mask,
         int words, int offset, std::uint64_t last_word_bits) {
  BitCounts n;
  for (int w = 0; w < words; ++w) {
    const std::uint64_t in_row = w + 1 == words ? last_word_bits : ~std::uint64_t{0};
    const std::uint64_t valid = ~(window(q_mask, offset, w) | c_mask[w]) & in_row;
    const std::uint64_t re = (window(q_re, offset, w) ^ c_re[w]) & valid;
    const std::uint64_t im = (window(q_im, offset, w) ^ c_im[w]) & valid;
    n.differing += static_cast<std::uint64_t>(std::popcount(re) + std::popcount(im));
    n.valid += 2 * static_cast<std::uint64_t>(std::popcount(valid));
  }
  return n;
}

/// The query prepared once per match: features and mask doubled.
struct PreparedQuery {
  DoubledRows features;
  DoubledRows mask;
};

PreparedQuery prepare(const IrisDescriptor& q) {
  return {doubleRows(q.features, q.words, q.image.columns),
          doubleRows(q.mask, q.words, q.image.columns)};
}

/// Eq. 6 at shift `shift` (candidate column j against query column j - shift).
double hamming(const PreparedQuery& pq, const IrisDescriptor& q, const IrisDescriptor& c,
               int shift) {
  const int n = q.image.columns;
  const int offset = (n - shift % n) % n;
  const int tail = n % 64;
  const std::uint64_t last = tail == 0 ? ~std::uint64_t{0} : (std::uint64_t{1} << tail) - 1;
  const std::size_t stride = idx(pq.features.stride);
  BitCounts total;
  for (int s = 0; s < q.scales; ++s) {
    for (int r = 0; r < q.image.rows; ++r) {
      const std::size_t re = idx(s * q.image.rows + r);
      const std::size_t im = idx((s + q.scales) * q.image.rows + r);
      const BitCounts b = countRow(
          pq.features.bits.data() + re * stride, pq.features.bits.data() + im * stride,
          pq.mask.bits.data() + re * stride, c.featureRow(s, r).data(),
          c.featureRow(s + q.scales, r).data(), c.maskRow(s, r).data(), q.words, offset, last);
      total.differing += b.differing;
      total.valid += b.valid;
    }
  }
  return total.valid == 0 ? 1.0
                          : static_cast<double>(total.differing) / static_cast<double>(total.valid);
}

/// The best peak of the correlation among shifts whose signed value lies in
/// [lo, hi] columns.
int peakIn(const std::vector<float>& correlation, int lo, int hi) {
  const int n = static_cast<int>(correlation.size());
  int best = (lo + n) % n;
  for (int s = lo; s <= hi; ++s) {
    const int k = (s + n) % n;
    if (correlation[idx(k)] > correlation[idx(best)]) best = k;
  }
  return best;
}

/// Hamming distance around one peak: the peak and `radius` shifts either side.
Match searchAround(const PreparedQuery& pq, const IrisDescriptor& q, const IrisDescriptor& c,
                   int peak, int radius) {
  const int n = q.image.columns;
  Match best;
  best.distance = 2.0;
  for (int d = -radius; d <= radius; ++d) {
    const int shift = ((peak + d) % n + n) % n;
    const double distance = hamming(pq, q, c, shift);
    if (distance < best.distance) {
      best.distance = distance;
      best.shift = shift;
    }
  }
  return best;
}

/// Fills the yaw of T_query_candidate from the shift: the candidate shows the
/// query's column j at column j + shift, i.e. the scene turned by +shift
/// columns, so the candidate's frame is turned by -shift columns.
Match withYaw(Match m, int columns) {
  const int signed_shift = m.shift > columns / 2 ? m.shift - columns : m.shift;
  m.yaw_rad = -2.0 * 3.14159265358979323846 * signed_shift / columns;
  m.reversed = std::abs(signed_shift) > columns / 4;
  return m;
}

}  // namespace

double irisHammingDistance(const IrisDescriptor& query, const IrisDescriptor& candidate,
                           int shift) {
  checkComparable(query, candidate);
  return hamming(prepare(query), query, candidate, shift);
}

Match matchIris(const IrisDescriptor& query, const IrisDescriptor& candidate,
                const IrisConfig& config) {
  const std::vector<float> correlation = irisShiftCorrelation(query, candidate);
  const int n = query.image.columns;
  const PreparedQuery pq = prepare(query);
  // Same driving direction: |yaw| <= 90 deg; opposite: the rest of the circle,
  // where a revisit the other way round puts the scene half a turn away. Each
  // direction's peak is scored, and the neighbours of the better one searched
  // (the peak may be a column off): 7 Hamming distances instead of 10.
  const int forward = peakIn(correlation, -n / 4, n / 4);
  int peak = forward;
  if (config.match_reverse) {
    const int reverse = peakIn(correlation, n / 4 + 1, 3 * n / 4 - 1);
    if (hamming(pq, query, candidate, reverse) < hamming(pq, query, candidate, forward))
      peak = reverse;
  }
  const Match best = searchAround(pq, query, candidate, peak, config.neighbour_shifts);
  return withYaw(best, n);
}

LidarIris::LidarIris(const IrisConfig& config) : config_(config) {
  validate(config_);
}

std::size_t LidarIris::keySize() const {
  return idx(config_.rows);
}

std::shared_ptr<const PlaceDescriptor> LidarIris::describe(const core::PointCloud& scan) const {
  return std::make_shared<const IrisDescriptor>(describeIris(scan, config_));
}

Match LidarIris::match(const PlaceDescriptor& query, const PlaceDescriptor& candidate) const {
  const auto* q = dynamic_cast<const IrisDescriptor*>(&query);
  const auto* c = dynamic_cast<const IrisDescriptor*>(&candidate);
  check(q != nullptr && c != nullptr, "match: both descriptors must be LiDAR-Iris descriptors");
  return matchIris(*q, *c, config_);
}

}  // namespace dcl::place
