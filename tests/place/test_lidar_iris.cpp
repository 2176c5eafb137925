#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <vector>

#include <gtest/gtest.h>

#include <dcl/core/error.hpp>
#include <dcl/place/lidar_iris.hpp>

#include "descriptor_test_data.hpp"

namespace dcl::place {
namespace {

using test::kittiScan;

core::PointCloud cloudOf(std::initializer_list<Eigen::Vector3f> points) {
  core::PointCloud c;
  c.points = points;
  return c;
}

/// One descriptor per frame, computed once for the whole suite.
const IrisDescriptor& kitti(int frame) {
  static std::map<int, IrisDescriptor> cache;
  auto it = cache.find(frame);
  if (it == cache.end()) it = cache.emplace(frame, describeIris(kittiScan(frame))).first;
  return it->second;
}

TEST(IrisImage, BinsRangeAngleAndHeightAsTheOriginal) {
  const IrisImage image =
      makeIrisImage(cloudOf({{10.5F, 0.0F, -1.73F},   // row 10, column 0, bit ceil(3.27) = 4
                             {0.0F, 5.2F, 0.5F},      // row 5, column 90, bit 6
                             {-3.0F, -0.01F, 9.0F},   // column 180, bit 7 (clamped)
                             {0.0F, -120.0F, -8.0F},  // beyond 80 m: last row; bit 0
                             {std::numeric_limits<float>::quiet_NaN(), 1.0F, 0.0F}}));
  ASSERT_EQ(image.rows, 80);
  ASSERT_EQ(image.columns, 360);
  EXPECT_EQ(image.at(10, 0), 1U << 4);
  EXPECT_EQ(image.at(5, 90), 1U << 6);
  EXPECT_EQ(image.at(3, 180), 1U << 7);
  EXPECT_EQ(image.at(79, 270), 1U << 0);
  int occupied = 0;
  for (std::uint8_t c : image.cells) occupied += c != 0 ? 1 : 0;
  EXPECT_EQ(occupied, 4);  // the NaN point is skipped
}

TEST(IrisImage, ColumnsAreCentredOnWholeDegrees) {
  const auto at = [](double deg) {
    const double r = test::radians(deg);
    return makeIrisImage(cloudOf(
        {{static_cast<float>(20 * std::cos(r)), static_cast<float>(20 * std::sin(r)), 0.0F}}));
  };
  EXPECT_NE(at(0.4).at(20, 0), 0);
  EXPECT_NE(at(0.6).at(20, 1), 0);
  EXPECT_NE(at(359.6).at(20, 0), 0);  // wraps, as a circle should
  EXPECT_NE(at(-90.3).at(20, 270), 0);
}

/// Sets, in `image`, the bits a point may take by the definition computed in
/// double precision; within `slack` of a bin edge (column, ring or slab) a
/// point may take either side, and with `either` false it takes none.
void referenceBits(IrisImage& image, const Eigen::Vector3f& p, double slack, bool either) {
  const double x = p.x(), y = p.y(), z = p.z();
  if (!std::isfinite(x) || !std::isfinite(y) || !std::isfinite(z)) return;
  double yaw = test::degrees(std::atan2(y, x));
  if (yaw < 0.0) yaw += 360.0;
  const double range = std::hypot(x, y);
  const double height = z + 5.0;
  const auto choices = [&](double v, double edge_offset) {
    // The bins v may fall in: floor(v + offset), or both neighbours near an edge.
    const double f = v + edge_offset;
    const double frac = f - std::floor(f);
    std::vector<int> bins{static_cast<int>(std::floor(f))};
    if (frac < slack) bins.push_back(bins[0] - 1);
    if (frac > 1.0 - slack) bins.push_back(bins[0] + 1);
    return bins;
  };
  const std::vector<int> columns = choices(yaw, 0.5);
  const std::vector<int> rows = choices(range, 0.0);
  const std::vector<int> slabs = choices(height, 1.0);  // ceil(h) = floor(h + 1) off edges
  if (!either && columns.size() + rows.size() + slabs.size() > 3) return;
  for (int c : columns)
    for (int r : rows)
      for (int s : slabs)
        image.cells[static_cast<std::size_t>(std::clamp(r, 0, 79) * 360 + (c + 360) % 360)] |=
            static_cast<std::uint8_t>(1U << std::clamp(s, 0, 7));
}

TEST(IrisImage, VectorisedBinningAgreesWithTheDefinitionOnARealScan) {
  // The vector paths (eight and four points at a time) and the scalar tail
  // against std::atan2 and std::hypot in double: every point off a bin edge
  // lands where the definition puts it, and nothing lands anywhere else.
  core::PointCloud scan = kittiScan(94);
  scan.points.resize(scan.points.size() / 8 * 8 - 5);  // leaves a four and a scalar tail
  scan.points.push_back({std::numeric_limits<float>::infinity(), 1.0F, 0.0F});
  const IrisImage image = makeIrisImage(scan);
  IrisImage sure{80, 360, std::vector<std::uint8_t>(80 * 360, 0)};
  IrisImage possible = sure;
  for (const Eigen::Vector3f& p : scan.points) {
    referenceBits(sure, p, 1e-4, false);
    referenceBits(possible, p, 1e-4, true);
  }
  int occupied = 0;
  for (std::size_t i = 0; i < image.cells.size(); ++i) {
    EXPECT_EQ(image.cells[i] & sure.cells[i], sure.cells[i]) << "cell " << i;
    EXPECT_EQ(image.cells[i] & ~possible.cells[i], 0) << "cell " << i;
    occupied += image.cells[i] != 0 ? 1 : 0;
  }
  EXPECT_GT(occupied, 5000);
}

TEST(IrisImage, EachSensorHasItsOwnHeightEncoding) {
  // KITTI's HDL-64 at 1.73 m: ground in bit 4; a VLP-16 at 0.8 m: ground in bit 2.
  IrisConfig hdl;
  IrisConfig vlp;
  vlp.sensor = "vlp16";
  EXPECT_EQ(makeIrisImage(cloudOf({{5.5F, 0.0F, -1.73F}}), hdl).at(5, 0), 1U << 4);
  EXPECT_EQ(makeIrisImage(cloudOf({{5.5F, 0.0F, -0.8F}}), vlp).at(5, 0), 1U << 2);
  EXPECT_EQ(makeIrisImage(cloudOf({{5.5F, 0.0F, 4.5F}}), vlp).at(5, 0), 1U << 7);
  EXPECT_EQ(heightEncodingFor("hdl64").lowest, -5.0);
  EXPECT_EQ(heightEncodingFor("vlp16").lowest, -2.0);
  EXPECT_THROW(heightEncodingFor("livox"), core::Error);  // no silent fall-through
  IrisConfig custom;
  custom.sensor = "livox";
  custom.custom_height = true;
  custom.height = {-1.0, 0.5};
  EXPECT_EQ(makeIrisImage(cloudOf({{5.5F, 0.0F, 0.2F}}), custom).at(5, 0), 1U << 3);  // ceil(2.4)
}

TEST(IrisRowKey, IsTheRowL2NormAndInvariantToRotation) {
  IrisImage image{2, 8, {3, 4, 0, 0, 0, 0, 0, 0, /**/ 1, 1, 1, 1, 1, 1, 1, 1}};
  const std::vector<float> key = irisRowKey(image);
  EXPECT_FLOAT_EQ(key[0], 5.0F);
  EXPECT_FLOAT_EQ(key[1], std::sqrt(8.0F));
  // A yaw that is a whole number of columns only permutes each row (Eq. 5).
  const IrisDescriptor a = describeIris(kittiScan(0));
  const IrisDescriptor b = describeIris(test::rotatedZ(kittiScan(0), test::radians(90)));
  for (int r = 0; r < 80; ++r)
    EXPECT_NEAR(a.row_key[r], b.row_key[r], 0.02 * a.row_key[r] + 1.0) << r;
}

TEST(IrisFeatures, EmptyRowsAreMaskedAndPaddingIsZero) {
  const IrisDescriptor& d = kitti(0);
  ASSERT_EQ(d.words, 6);
  ASSERT_EQ(d.features.size(), 8U * 80 * 6);
  ASSERT_EQ(d.mask.size(), 4U * 80 * 6);
  const std::uint64_t padding = ~((std::uint64_t{1} << 40) - 1);  // columns 360..383
  for (int r = 0; r < 80; ++r) {
    const bool empty = d.row_key[r] == 0.0F;
    for (int s = 0; s < 4; ++s) {
      EXPECT_EQ(d.maskRow(s, r)[5] & padding, 0U);
      EXPECT_EQ(d.featureRow(s, r)[5] & padding, 0U);
      if (empty) {
        EXPECT_EQ(d.maskRow(s, r)[0], ~std::uint64_t{0});
      }
    }
  }
  EXPECT_EQ(d.row_key[0], 0.0F);  // the car itself blocks the first metre
}

TEST(IrisFeatures, SameImageGivesTheSameBits) {
  const IrisDescriptor& d = kitti(1);
  const IrisDescriptor again = describeIrisImage(d.image);
  EXPECT_EQ(again.features, d.features);
  EXPECT_EQ(again.mask, d.mask);
  EXPECT_EQ(again.row_key, d.row_key);
  EXPECT_THROW(describeIrisImage(IrisImage{79, 360, std::vector<std::uint8_t>(79 * 360)}),
               core::Error);
}

// The original LiDAR-Iris (OpenCV) on the same scans, forward match.
TEST(IrisMatch, AgreesWithTheOriginalOnRealKittiPairs) {
  EXPECT_NEAR(matchIris(kitti(0), kitti(1)).distance, 0.185, 0.02);
  EXPECT_NEAR(matchIris(kitti(94), kitti(95)).distance, 0.144, 0.02);
  EXPECT_NEAR(matchIris(kitti(198), kitti(199)).distance, 0.153, 0.02);
  EXPECT_NEAR(matchIris(kitti(0), kitti(198)).distance, 0.455, 0.02);
}

TEST(IrisMatch, SeparatesConsecutiveFramesFromDifferentPlaces) {
  for (const auto& [a, b] :
       {std::pair{0, 1}, {1, 2}, {2, 3}, {3, 4}, {4, 5}, {94, 95}, {198, 199}}) {
    const double d = matchIris(kitti(a), kitti(b)).distance;
    EXPECT_GT(d, 0.10) << a << " vs " << b;
    EXPECT_LT(d, 0.20) << a << " vs " << b;
  }
  for (const auto& [a, b] : {std::pair{0, 94}, {0, 198}, {94, 198}, {5, 199}, {95, 1}}) {
    const double d = matchIris(kitti(a), kitti(b)).distance;
    EXPECT_GT(d, 0.40) << a << " vs " << b;
    EXPECT_LT(d, 0.55) << a << " vs " << b;
  }
}

TEST(IrisMatch, FindsTheYawOfRotatedCopies) {
  const core::PointCloud scan = kittiScan(2);
  const IrisDescriptor& query = kitti(2);
  for (double deg : {0.0, 17.0, 37.4, -64.6, 90.0, 135.2, -151.0, 179.0}) {
    const Match m = matchIris(query, describeIris(test::rotatedZ(scan, test::radians(deg))));
    // The candidate is the scene turned by +deg: its frame is turned by -deg.
    EXPECT_NEAR(std::remainder(test::degrees(m.yaw_rad) + deg, 360.0), 0.0, 2.0) << deg;
    EXPECT_LT(m.distance, 0.12) << deg;
    EXPECT_EQ(m.reversed, std::abs(deg) > 90.0) << deg;
  }
}

TEST(IrisMatch, FindsAnOppositeDirectionRevisit) {
  // Frame 1 seen driving the other way, 1.5 m to the side
  // and 0.5 m along: half a turn plus an offset, against frame 0.
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(test::radians(178.0), Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(0.5, 1.5, 0.0);
  const IrisDescriptor revisit = describeIris(core::transformed(kittiScan(1), T));
  const Match m = matchIris(kitti(0), revisit);
  EXPECT_TRUE(m.reversed);
  EXPECT_LT(m.distance, 0.35);  // DESIGN.md: accepted below 0.3 for the same lane
  EXPECT_NEAR(std::remainder(test::degrees(m.yaw_rad) + 178.0, 360.0), 0.0, 3.0);
  IrisConfig forward_only;
  forward_only.match_reverse = false;
  EXPECT_GT(matchIris(kitti(0), revisit, forward_only).distance, 0.4);
}

TEST(IrisMatch, HammingIsZeroOnItselfAndRejectsOtherDimensions) {
  EXPECT_EQ(irisHammingDistance(kitti(0), kitti(0), 0), 0.0);
  EXPECT_GT(irisHammingDistance(kitti(0), kitti(0), 5), 0.1);
  IrisConfig small;
  small.rows = 40;
  small.max_range = 40;
  EXPECT_THROW(matchIris(kitti(0), describeIris(kittiScan(0), small)), core::Error);
}

TEST(LidarIrisDescriptor, WorksBehindTheInterface) {
  const std::unique_ptr<Descriptor> iris = makeDescriptor();
  ASSERT_EQ(iris->kind(), DescriptorKind::kLidarIris);
  EXPECT_EQ(iris->keySize(), 80U);
  const auto a = iris->describe(kittiScan(94));
  const auto b = iris->describe(kittiScan(95));
  EXPECT_EQ(a->key().size(), 80U);
  EXPECT_NEAR(iris->match(*a, *b).distance, matchIris(kitti(94), kitti(95)).distance, 1e-12);
  DescriptorConfig sc;
  sc.kind = "scancontext";
  EXPECT_THROW((void)iris->match(*a, *makeDescriptor(sc)->describe(kittiScan(0))), core::Error);
  DescriptorConfig bad;
  bad.kind = "m2dp";
  EXPECT_THROW(makeDescriptor(bad), core::Error);
  bad = {};
  bad.iris.log_gabor.multiplier = 1.0;
  EXPECT_THROW(makeDescriptor(bad), core::Error);
  EXPECT_EQ(parseDescriptorKind("scan-context"), DescriptorKind::kScanContext);
  EXPECT_EQ(toString(DescriptorKind::kLidarIris), "iris");
}

}  // namespace
}  // namespace dcl::place
