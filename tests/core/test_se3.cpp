#include <random>

#include <gtest/gtest.h>

#include <dcl/core/se3.hpp>

namespace dcl::core {
namespace {

Vector6d randomTangent(std::mt19937& rng, double scale) {
  std::uniform_real_distribution<double> u(-scale, scale);
  Vector6d xi;
  for (int i = 0; i < 6; ++i) xi[i] = u(rng);
  return xi;
}

TEST(Se3, HatAndVeeAreInverseAndGiveTheCrossProduct) {
  const Eigen::Vector3d v(0.3, -1.2, 2.5), w(-0.7, 0.1, 0.4);
  EXPECT_TRUE((hat(v) * w).isApprox(v.cross(w)));
  EXPECT_TRUE(vee(hat(v)).isApprox(v));
}

TEST(Se3, ExpOfRotationVectorMatchesAngleAxis) {
  const Eigen::Vector3d axis = Eigen::Vector3d(1, 2, -0.5).normalized();
  const Eigen::Matrix3d R = expSO3(0.8 * axis);
  EXPECT_TRUE(R.isApprox(Eigen::AngleAxisd(0.8, axis).toRotationMatrix(), 1e-12));
}

TEST(Se3, LogInvertsExpAcrossTheRangeOfAngles) {
  std::mt19937 rng(7);
  for (double angle : {0.0, 1e-9, 1e-5, 0.1, 1.0, 3.0, M_PI - 1e-7}) {
    const Eigen::Vector3d axis = Eigen::Vector3d::Random().normalized();
    const Eigen::Vector3d omega = angle * axis;
    const Eigen::Vector3d back = logSO3(expSO3(omega));
    EXPECT_NEAR((back - omega).norm(), 0.0, 1e-9) << "angle " << angle;
  }
}

TEST(Se3, LogAtPiGivesAnglePi) {
  const Eigen::Matrix3d R = Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  EXPECT_NEAR(logSO3(R).norm(), M_PI, 1e-12);
  EXPECT_NEAR(std::abs(logSO3(R).z()), M_PI, 1e-12);
}

TEST(Se3, SE3LogInvertsExp) {
  std::mt19937 rng(11);
  for (int i = 0; i < 100; ++i) {
    const Vector6d xi = randomTangent(rng, 2.0);
    EXPECT_LT((logSE3(expSE3(xi)) - xi).norm(), 1e-9);
  }
}

TEST(Se3, SE3ExpOfPureTranslationIsTheTranslation) {
  Vector6d xi = Vector6d::Zero();
  xi.head<3>() << 1.0, -2.0, 3.0;
  const Eigen::Isometry3d T = expSE3(xi);
  EXPECT_TRUE(T.linear().isIdentity());
  EXPECT_TRUE(T.translation().isApprox(Eigen::Vector3d(1.0, -2.0, 3.0)));
}

TEST(Se3, LeftJacobianInverseIsTheInverse) {
  for (double angle : {0.0, 1e-8, 0.5, 2.0, 3.0}) {
    const Eigen::Vector3d omega = angle * Eigen::Vector3d(0.2, -0.5, 0.8).normalized();
    const Eigen::Matrix3d product = leftJacobianSO3(omega) * leftJacobianInverseSO3(omega);
    EXPECT_TRUE(product.isIdentity(1e-9)) << "angle " << angle;
  }
}

TEST(Se3, AdjointMovesTangentsThroughAPose) {
  std::mt19937 rng(3);
  const Eigen::Isometry3d T = expSE3(randomTangent(rng, 1.5));
  const Vector6d xi = randomTangent(rng, 0.3);
  const Eigen::Isometry3d lhs = T * expSE3(xi) * T.inverse();
  const Eigen::Isometry3d rhs = expSE3(adjoint(T) * xi);
  EXPECT_TRUE(lhs.matrix().isApprox(rhs.matrix(), 1e-9));
}

TEST(Se3, ProjectToSO3RecoversANoisyRotation) {
  const Eigen::Matrix3d R = expSO3(Eigen::Vector3d(0.3, -0.2, 1.1));
  Eigen::Matrix3d noisy = R;
  noisy(0, 1) += 1e-3;
  noisy(2, 2) -= 2e-3;
  const Eigen::Matrix3d P = projectToSO3(noisy);
  EXPECT_NEAR(P.determinant(), 1.0, 1e-12);
  EXPECT_TRUE((P.transpose() * P).isIdentity(1e-12));
  EXPECT_LT(rotationAngle(P.transpose() * R), 2e-3);
}

TEST(Se3, ProjectToSO3FixesAReflection) {
  Eigen::Matrix3d M = Eigen::Matrix3d::Identity();
  M(2, 2) = -1.0;  // a reflection: the nearest rotation has determinant +1
  EXPECT_NEAR(projectToSO3(M).determinant(), 1.0, 1e-12);
}

TEST(Se3, InterpolationHitsEndsAndMiddle) {
  const Eigen::Isometry3d A = makePose(Eigen::Vector3d(0, 0, 0), Eigen::Matrix3d::Identity());
  const Eigen::Isometry3d B = makePose2d(2.0, 4.0, 1.0);
  EXPECT_TRUE(interpolate(A, B, 0.0).isApprox(A));
  EXPECT_TRUE(interpolate(A, B, 1.0).isApprox(B));
  const Eigen::Isometry3d M = interpolate(A, B, 0.5);
  EXPECT_TRUE(M.translation().isApprox(Eigen::Vector3d(1.0, 2.0, 0.0)));
  EXPECT_NEAR(rotationAngle(M.linear()), 0.5, 1e-12);
  const Eigen::Isometry3d G = interpolateGeodesic(A, B, 0.5);
  EXPECT_NEAR(rotationAngle(G.linear()), 0.5, 1e-12);
  EXPECT_TRUE(interpolateGeodesic(A, B, 1.0).isApprox(B, 1e-12));
}

TEST(Se3, MakePoseNormalisesTheQuaternion) {
  const Eigen::Quaterniond q(2.0, 0.0, 0.0, 2.0);  // 90 deg about z, not unit length
  const Eigen::Isometry3d T = makePose(Eigen::Vector3d(1, 2, 3), q);
  EXPECT_NEAR(T.linear().determinant(), 1.0, 1e-12);
  EXPECT_NEAR(rad2deg(rotationAngle(T.linear())), 90.0, 1e-9);
  EXPECT_DOUBLE_EQ(deg2rad(180.0), M_PI);
}

}  // namespace
}  // namespace dcl::core
