#pragma once
// Pose helpers shared by the optimiser tests: random perturbations of a
// T_cw and the position / rotation errors between two of them.
#include <Eigen/Geometry>
#include <cmath>
#include <random>

namespace dynaorb::test {

constexpr double kDeg = M_PI / 180.0;

inline Eigen::Vector3d random_unit(std::mt19937& rng) {
  std::normal_distribution<double> g(0, 1);
  return Eigen::Vector3d(g(rng), g(rng), g(rng)).normalized();
}

// T_cw with the rotation turned by `angle` about a random axis and the camera centre moved by
// `shift` in a random direction.
inline Eigen::Isometry3d perturb(const Eigen::Isometry3d& T, double shift, double angle,
                                 std::mt19937& rng) {
  const Eigen::Vector3d center = -(T.rotation().transpose() * T.translation());
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  out.linear() = Eigen::AngleAxisd(angle, random_unit(rng)).toRotationMatrix() * T.rotation();
  out.translation() = -out.rotation() * (center + shift * random_unit(rng));
  return out;
}

inline double center_error(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return (a.inverse().translation() - b.inverse().translation()).norm();
}

inline double rotation_error_deg(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return Eigen::AngleAxisd(a.rotation() * b.rotation().transpose()).angle() / kDeg;
}

}  // namespace dynaorb::test
