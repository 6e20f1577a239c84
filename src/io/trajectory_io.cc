#include "dynaorb/io/trajectory_io.h"

#include <cstdio>
#include <fstream>
#include <iomanip>

#include "dynaorb/io/errors.h"
#include "dynaorb/io/text_table.h"

namespace dynaorb::io {

namespace {
std::ofstream open_out(const std::string& path) {
  std::ofstream out(path);
  if (!out) throw InputError(path, 0, "cannot write trajectory file");
  return out;
}
}  // namespace

void write_tum(const std::string& path, const Trajectory& trajectory) {
  std::ofstream out = open_out(path);
  out << "# timestamp tx ty tz qx qy qz qw\n" << std::fixed;
  for (const StampedPose& p : trajectory) {
    Eigen::Quaterniond q(p.pose.linear());
    q.normalize();
    const Eigen::Vector3d& t = p.pose.translation();
    out << std::setprecision(6) << p.stamp << std::setprecision(9) << ' ' << t.x() << ' ' << t.y()
        << ' ' << t.z() << ' ' << q.x() << ' ' << q.y() << ' ' << q.z() << ' ' << q.w() << '\n';
  }
  if (!out) throw InputError(path, 0, "write failed");
}

void write_kitti(const std::string& path, const Trajectory& trajectory) {
  std::ofstream out = open_out(path);
  out << std::scientific << std::setprecision(9);
  for (const StampedPose& p : trajectory) {
    const Eigen::Matrix<double, 3, 4> m = p.pose.matrix().topRows<3>();
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c) out << m(r, c) << ((r == 2 && c == 3) ? '\n' : ' ');
  }
  if (!out) throw InputError(path, 0, "write failed");
}

Trajectory read_tum(const std::string& path) {
  Trajectory trajectory;
  for (const TextRow& row : read_text_table(path)) {
    require_fields(path, row, 8, "timestamp tx ty tz qx qy qz qw");
    double v[8];
    const char* what[] = {"timestamp", "tx", "ty", "tz", "qx", "qy", "qz", "qw"};
    for (int i = 0; i < 8; ++i) v[i] = parse_double(path, row, i, what[i]);
    Eigen::Quaterniond q(v[7], v[4], v[5], v[6]);
    if (std::abs(q.norm() - 1.0) > 1e-2)
      throw InputError(path, row.line, "quaternion is not unit length");
    if (!trajectory.empty() && v[0] <= trajectory.back().stamp)
      throw InputError(path, row.line, "timestamps are not increasing");
    trajectory.push_back({v[0], pose_from_tq({v[1], v[2], v[3]}, q)});
  }
  return trajectory;
}

Trajectory read_kitti(const std::string& path, const std::vector<double>& stamps) {
  Trajectory trajectory;
  const std::vector<TextRow> rows = read_text_table(path);
  if (!stamps.empty() && stamps.size() < rows.size())
    throw InputError(path, 0,
                     "has " + std::to_string(rows.size()) + " poses but only " +
                         std::to_string(stamps.size()) + " timestamps");
  for (size_t k = 0; k < rows.size(); ++k) {
    const TextRow& row = rows[k];
    require_fields(path, row, 12, "3x4 row-major pose");
    Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
    for (int i = 0; i < 12; ++i) m(i / 4, i % 4) = parse_double(path, row, i, "pose element");
    Pose pose = Pose::Identity();
    Eigen::Matrix3d rot = m.topLeftCorner<3, 3>();
    if ((rot * rot.transpose() - Eigen::Matrix3d::Identity()).norm() > 1e-3)
      throw InputError(path, row.line, "rotation part is not orthonormal");
    pose.linear() = Eigen::Quaterniond(rot).normalized().toRotationMatrix();
    pose.translation() = m.topRightCorner<3, 1>();
    trajectory.push_back({stamps.empty() ? static_cast<double>(k) : stamps[k], pose});
  }
  return trajectory;
}

}  // namespace dynaorb::io
