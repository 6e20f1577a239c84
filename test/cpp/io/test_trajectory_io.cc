#include <gtest/gtest.h>

#include "../test_util.h"
#include "dynaorb/io/errors.h"
#include "dynaorb/io/trajectory_io.h"

namespace dynaorb {
namespace {

Trajectory sample() {
  Trajectory t;
  for (int i = 0; i < 5; ++i) {
    Eigen::Quaterniond q(Eigen::AngleAxisd(0.1 * i, Eigen::Vector3d(0.2, 1.0, -0.3).normalized()));
    t.push_back({100.0 + 0.1 * i, pose_from_tq({0.5 * i, -0.2 * i, 1.0 + i}, q)});
  }
  return t;
}

TEST(TrajectoryIo, TumRoundTrip) {
  test::ScratchDir dir;
  const auto path = (dir.path() / "t.tum").string();
  const Trajectory t = sample();
  io::write_tum(path, t);
  const Trajectory r = io::read_tum(path);
  ASSERT_EQ(r.size(), t.size());
  for (size_t i = 0; i < t.size(); ++i) {
    EXPECT_NEAR(r[i].stamp, t[i].stamp, 1e-6);
    EXPECT_TRUE(r[i].pose.isApprox(t[i].pose, 1e-7));
  }
}

TEST(TrajectoryIo, KittiRoundTrip) {
  test::ScratchDir dir;
  const auto path = (dir.path() / "t.kitti").string();
  const Trajectory t = sample();
  io::write_kitti(path, t);
  std::vector<double> stamps;
  for (const auto& p : t) stamps.push_back(p.stamp);
  const Trajectory r = io::read_kitti(path, stamps);
  ASSERT_EQ(r.size(), t.size());
  for (size_t i = 0; i < t.size(); ++i) EXPECT_TRUE(r[i].pose.isApprox(t[i].pose, 1e-7));
  EXPECT_THROW(io::read_kitti(path, {0.0, 1.0}), InputError);  // fewer stamps than poses
}

TEST(TrajectoryIo, BadRowsAreNamed) {
  test::ScratchDir dir;
  const auto path = dir.write("bad.tum", "# header\n1.0 0 0 0 0 0 0 1\n2.0 0 0 0 0 0\n").string();
  try {
    io::read_tum(path);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("bad.tum:3"), std::string::npos) << e.what();
  }
  EXPECT_THROW(io::read_tum(dir.write("order.tum", "2.0 0 0 0 0 0 0 1\n1.0 0 0 0 0 0 0 1\n").string()),
               InputError);
  EXPECT_THROW(io::read_tum(dir.write("quat.tum", "1.0 0 0 0 0 0 0 3\n").string()), InputError);
  EXPECT_THROW(io::read_kitti(dir.write("k.txt", "1 0 0 0 0 1 0 0 0 0 5 0\n").string()), InputError);
}

}  // namespace
}  // namespace dynaorb
