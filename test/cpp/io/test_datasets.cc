#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>

#include "../test_util.h"
#include "dynaorb/io/dataset.h"
#include "dynaorb/io/errors.h"

namespace dynaorb {
namespace {

using test::fs::path;
using test::ScratchDir;
using test::shared_data;

const char* kTumFragment = "tum/rgbd_dataset_freiburg3_walking_xyz_fragment";

// Runs `f`, expects an InputError whose text contains every one of `parts`.
template <typename F>
void expect_error(F f, std::initializer_list<std::string> parts) {
  try {
    f();
    ADD_FAILURE() << "no InputError thrown";
  } catch (const InputError& e) {
    for (const std::string& p : parts) EXPECT_NE(std::string(e.what()).find(p), std::string::npos) << e.what();
  }
}

TEST(TumDataset, LoadsTheFragment) {
  DYNAORB_REQUIRE_SHARED();
  auto d = open_dataset("tum", (shared_data() / kTumFragment).string());
  EXPECT_EQ(d->sensor(), Sensor::kRGBD);
  ASSERT_EQ(d->size(), 2u);
  Frame f = d->load(0);
  EXPECT_EQ(f.image.size(), cv::Size(640, 480));
  EXPECT_EQ(f.image.channels(), 3);
  EXPECT_EQ(f.depth.type(), CV_16UC1);
  EXPECT_NEAR(f.stamp, 1341846313.592026, 1e-6);
  EXPECT_GT(d->ground_truth().size(), 100u);
  Settings s = d->default_settings();  // freiburg3 from the folder name
  EXPECT_DOUBLE_EQ(s.camera.fx, 535.4);
  EXPECT_DOUBLE_EQ(*s.camera.depth_map_factor, 5000.0);
}

class BrokenTum : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!test::fs::is_directory(shared_data() / kTumFragment)) GTEST_SKIP() << "no shared data";
    seq = dir.path() / "rgbd_dataset_freiburg3_copy";
    test::copy_tree(shared_data() / kTumFragment, seq);
  }
  ScratchDir dir;
  path seq;
};

TEST_F(BrokenTum, MissingImageNamesListAndLine) {
  test::fs::remove(seq / "rgb" / "1341846316.570121.png");
  expect_error([&] { open_tum(seq.string(), {}); }, {"rgb.txt:5", "missing image", "1341846316.570121.png"});
}

TEST_F(BrokenTum, CorruptPngNamesTheFile) {
  std::ofstream(seq / "depth" / "1341846313.592088.png") << "not a png at all";
  auto d = open_tum(seq.string(), {});
  expect_error([&] { d->load(0); }, {"1341846313.592088.png", "cannot decode", "depth.txt:4"});
  EXPECT_NO_THROW(d->load(1));
}

TEST_F(BrokenTum, UnorderedStampsNameTheLine) {
  dir.write("rgbd_dataset_freiburg3_copy/rgb.txt",
            "# color images\n1341846316.570121 rgb/1341846316.570121.png\n"
            "1341846313.592026 rgb/1341846313.592026.png\n");
  expect_error([&] { open_tum(seq.string(), {}); }, {"rgb.txt:3", "not increasing"});
}

TEST_F(BrokenTum, MalformedRowAndMissingListAreNamed) {
  dir.write("rgbd_dataset_freiburg3_copy/depth.txt", "# depth\nabc depth/x.png\n");
  expect_error([&] { open_tum(seq.string(), {}); }, {"depth.txt:2", "timestamp"});
  test::fs::remove(seq / "rgb.txt");
  expect_error([&] { open_tum(seq.string(), {}); }, {"rgb.txt", "cannot open"});
}

TEST_F(BrokenTum, DepthAssociationDropsFarStamps) {
  dir.write("rgbd_dataset_freiburg3_copy/depth.txt",
            "1341846313.592088 depth/1341846313.592088.png\n"
            "1341846316.670146 depth/1341846316.570146.png\n");  // 0.1 s from its colour image
  auto d = open_tum(seq.string(), {});
  EXPECT_EQ(d->size(), 1u);
  ASSERT_EQ(d->warnings().size(), 1u);
  EXPECT_THROW(open_tum(seq.string(), DatasetOptions{Sensor::kStereo}), InputError);
}

TEST(KittiDataset, LoadsSequence06) {
  DYNAORB_REQUIRE_SHARED();
  auto d = open_dataset("kitti", (shared_data() / "kitti/sequences/06").string());
  EXPECT_EQ(d->sensor(), Sensor::kStereo);
  ASSERT_EQ(d->size(), 51u);
  Frame f = d->load(50);
  EXPECT_EQ(f.image.size(), cv::Size(1226, 370));
  EXPECT_EQ(f.right.size(), f.image.size());
  Trajectory gt = d->ground_truth();
  ASSERT_EQ(gt.size(), 51u);
  EXPECT_NEAR(gt[1].stamp, 0.1044989, 1e-9);
  EXPECT_NEAR(gt[1].pose.translation().z(), 1.198998, 1e-6);
  Settings s = d->default_settings();
  EXPECT_NEAR(s.camera.fx, 707.0912, 1e-6);
  EXPECT_NEAR(*s.camera.bf, 379.8145, 1e-3);
  EXPECT_EQ(s.camera.width, 1226);
  EXPECT_NO_THROW(s.validate(Sensor::kStereo));
}

TEST(KittiDataset, BadTimesAndCalibAreNamed) {
  DYNAORB_REQUIRE_SHARED();
  ScratchDir dir;
  path seq = dir.path() / "sequences" / "06";
  test::fs::create_directories(seq / "image_0");
  test::fs::create_directories(seq / "image_1");
  for (const char* cam : {"image_0", "image_1"})
    for (const char* name : {"000000.png", "000001.png"})
      test::fs::copy_file(shared_data() / "kitti/sequences/06" / cam / name, seq / cam / name);
  dir.write("sequences/06/times.txt", "0.0\n0.1\n0.2\n");
  expect_error([&] { open_kitti(seq.string(), {}); }, {"times.txt:3", "missing image", "000002.png"});
  dir.write("sequences/06/times.txt", "0.0\nzero\n");
  expect_error([&] { open_kitti(seq.string(), {}); }, {"times.txt:2", "timestamp"});
  dir.write("sequences/06/times.txt", "0.0\n0.1\n");
  dir.write("sequences/06/calib.txt", "P0: 1 0 0 0 0 1 0 0 0 0 1 0\n");
  auto d = open_kitti(seq.string(), {});
  expect_error([&] { d->default_settings(); }, {"calib.txt", "P1:"});
}

TEST(EurocDataset, LoadsStereoAndMono) {
  DYNAORB_REQUIRE_SHARED();
  auto d = open_dataset("euroc", (shared_data() / "euroc/V1_01_easy_micro").string());
  EXPECT_EQ(d->sensor(), Sensor::kStereo);
  ASSERT_EQ(d->size(), 95u);
  Frame f = d->load(0);
  EXPECT_EQ(f.image.size(), cv::Size(752, 480));
  EXPECT_FALSE(f.right.empty());
  Settings s = d->default_settings();
  EXPECT_TRUE(s.rectification.enabled());
  EXPECT_NEAR(s.camera.baseline(), 0.110, 0.002);  // EuRoC's 11 cm stereo baseline
  EXPECT_NO_THROW(s.validate(Sensor::kStereo));
  Trajectory gt = d->ground_truth();
  ASSERT_GT(gt.size(), 90u);
  // Body->camera: cam0 sits ~6.5 cm from the IMU in the body frame.
  EXPECT_NEAR(gt[0].pose.translation().x(), 0.878895, 0.1);

  auto mono = open_dataset("euroc", (shared_data() / "euroc/MH_05_difficult_head").string());
  EXPECT_EQ(mono->sensor(), Sensor::kMono);
  EXPECT_EQ(mono->size(), 250u);
  Settings ms = mono->default_settings();
  EXPECT_NEAR(ms.camera.fx, 458.654, 1e-9);
  EXPECT_TRUE(ms.camera.has_distortion());
  EXPECT_THROW(open_dataset("euroc", (shared_data() / "euroc/MH_05_difficult_head").string(),
                            DatasetOptions{Sensor::kStereo}),
               InputError);
}

TEST(EurocDataset, MissingCalibrationKeyIsNamed) {
  DYNAORB_REQUIRE_SHARED();
  ScratchDir dir;
  path mav0 = dir.path() / "mav0";
  test::fs::create_directories(mav0 / "cam0" / "data");
  const path src = shared_data() / "euroc/MH_05_difficult_head/mav0/cam0";
  std::ifstream csv(src / "data.csv");
  std::string header, first;
  std::getline(csv, header);
  std::getline(csv, first);
  const std::string name = first.substr(first.find(',') + 1);
  test::fs::copy_file(src / "data" / name, mav0 / "cam0" / "data" / name);
  dir.write("mav0/cam0/data.csv", header + "\n" + first + "\n");
  dir.write("mav0/cam0/sensor.yaml", "%YAML:1.0\nresolution: [752, 480]\n");
  expect_error([&] { open_euroc(dir.path().string(), {}); }, {"sensor.yaml", "intrinsics"});
  expect_error([&] { open_dataset("vicon", dir.path().string()); }, {"vicon"});
}

}  // namespace
}  // namespace dynaorb
