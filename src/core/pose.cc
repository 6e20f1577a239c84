#include "dynaorb/core/pose.h"

namespace dynaorb {

Pose pose_from_tq(const Eigen::Vector3d& t, const Eigen::Quaterniond& q) {
  Pose pose = Pose::Identity();
  pose.linear() = q.normalized().toRotationMatrix();
  pose.translation() = t;
  return pose;
}

}  // namespace dynaorb
