#include <gtest/gtest.h>

#include <filesystem>
#include <random>

#include "dynaorb/io/errors.h"
#include "dynaorb/io/trajectory_io.h"
#include "support/trajectory_files.h"

namespace dynaorb::node {
namespace {

namespace fs = std::filesystem;

Trajectory poses(double t0, int n) {
  Trajectory out;
  for (int i = 0; i < n; ++i) {
    StampedPose p;
    p.stamp = t0 + 0.1 * i;
    p.pose.linear() = Eigen::AngleAxisd(0.01 * i, Eigen::Vector3d(0.2, 1.0, 0.1).normalized()).toRotationMatrix();
    p.pose.translation() = Eigen::Vector3d(0.05 * i, -0.01 * i, 0.3 + 0.02 * i);
    out.push_back(p);
  }
  return out;
}

void expect_same(const Trajectory& a, const Trajectory& b) {
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) {
    EXPECT_NEAR(a[i].stamp, b[i].stamp, 1e-6);
    EXPECT_LT((a[i].pose.matrix() - b[i].pose.matrix()).cwiseAbs().maxCoeff(), 1e-8);
  }
}

fs::path scratch(const char* name) {
  fs::path dir = fs::temp_directory_path() / ("dynaorb_traj_" + std::to_string(std::random_device{}()));
  fs::create_directories(dir);
  return dir / name;
}

TEST(TrajectoryFiles, PassesAndMapsAreNamedBesideTheFile) {
  EXPECT_EQ(pass_path("/out/trajectory.tum", 1), "/out/trajectory.tum");
  EXPECT_EQ(pass_path("/out/trajectory.tum", 2), "/out/trajectory.pass2.tum");  // trajectory_recorder's names
  EXPECT_EQ(pass_path("run.d/final", 3), "run.d/final.pass3");
  EXPECT_EQ(map_path("/out/trajectory.pass2.tum", 1), "/out/trajectory.pass2.map1.tum");
}

TEST(TrajectoryFiles, OneMapIsOneFile) {
  const fs::path file = scratch("final.tum");
  const Trajectory t = poses(100.0, 12);
  const WrittenTrajectory w = write_trajectory_files(file.string(), t, {{0, t}});
  EXPECT_EQ(w.frames, 12u);
  ASSERT_EQ(w.files, std::vector<std::string>{file.string()});
  expect_same(io::read_tum(file.string()), t);
  fs::remove_all(file.parent_path());
}

TEST(TrajectoryFiles, AWriteReplacesTheFileWhole) {
  const fs::path file = scratch("final.tum");
  write_trajectory_files(file.string(), poses(100.0, 12), {});
  const Trajectory later = poses(200.0, 5);  // the shutdown's second write, after the mapping wait
  write_trajectory_files(file.string(), later, {});
  expect_same(io::read_tum(file.string()), later);
  EXPECT_FALSE(fs::exists(file.string() + ".part"));
  fs::remove_all(file.parent_path());
}

TEST(TrajectoryFiles, SeveralMapsEachGetTheirOwnFile) {
  const fs::path file = scratch("final.tum");
  const Trajectory first = poses(100.0, 5), second = poses(110.0, 9);
  // System::trajectory() is the largest map's.
  const WrittenTrajectory w = write_trajectory_files(file.string(), second, {{0, first}, {1, second}});
  EXPECT_EQ(w.frames, 9u);
  ASSERT_EQ(w.files.size(), 3u);
  expect_same(io::read_tum(file.string()), second);
  expect_same(io::read_tum(map_path(file.string(), 0)), first);
  expect_same(io::read_tum(map_path(file.string(), 1)), second);
  fs::remove_all(file.parent_path());
}

TEST(TrajectoryFiles, NothingTrackedWritesNothing) {
  const fs::path file = scratch("final.tum");
  const WrittenTrajectory w = write_trajectory_files(file.string(), {}, {});
  EXPECT_EQ(w.frames, 0u);
  EXPECT_TRUE(w.files.empty());
  EXPECT_FALSE(fs::exists(file));
  fs::remove_all(file.parent_path());
}

TEST(TrajectoryFiles, AnUnwritablePathIsAnInputErrorNamingIt) {
  const std::string file = "/nonexistent-dynaorb-folder/final.tum";
  try {
    write_trajectory_files(file, poses(0.0, 3), {});
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(file), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace dynaorb::node
