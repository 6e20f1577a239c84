// Li et al.'s stage end to end on a rendered stereo pair: a textured room
// seen by a moving stereo camera, with one fronto-parallel box that moves
// between the two frames. The box must end up inside the marked rectangles,
// the static scene mostly outside; depth is filled from the disparity; and
// degenerate input (no previous frame, no right image, a textureless pair, a
// monocular sensor) marks nothing and says why.
#include <gtest/gtest.h>

#include <memory>
#include <opencv2/core.hpp>
#include <string>

#include "dynaorb/dynamic/li_stage.h"
#include "dynaorb/io/errors.h"
#include "li_test_scene.h"

namespace dynaorb::dynamic {
namespace {

using namespace dynaorb::test::synth;
using dynaorb::test::li::StereoPair;

// Every member named, so -Wextra has nothing to say.
Context stereo_context(std::shared_ptr<const map::Calibration> calib, FrameData& cur,
                       std::shared_ptr<const FrameData> prev, cv::Mat dynamic = cv::Mat()) {
  return Context{Sensor::kStereo, std::move(calib), cur, std::move(prev), std::move(dynamic),
                 nullptr, nullptr, std::nullopt, nullptr, {}};
}

class LiStageTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    calib_ = make_calibration(Sensor::kStereo, 640, 480, 500, 0.1);
    pair_ = new StereoPair(dynaorb::test::li::render_stereo_pair(*calib_));
  }
  static void TearDownTestSuite() {
    delete pair_;
    pair_ = nullptr;
  }
  static std::shared_ptr<map::Calibration> calib_;
  static StereoPair* pair_;
};
std::shared_ptr<map::Calibration> LiStageTest::calib_;
StereoPair* LiStageTest::pair_ = nullptr;

TEST_F(LiStageTest, MarksTheMovingBoxAndLittleElse) {
  FrameData cur = *pair_->cur;
  Context ctx = stereo_context(calib_, cur, pair_->prev, cv::Mat::zeros(cur.grey.size(), CV_8UC1));
  LiStage stage;
  StageReport report;
  stage.process(ctx, report);

  const cv::Mat box = pair_->cur_view.object == dynaorb::test::li::kMoverIndex;
  const cv::Mat marked = ctx.dynamic != 0;
  const double box_px = cv::countNonZero(box);
  const double covered = cv::countNonZero(box & marked) / box_px;
  const double static_marked =
      cv::countNonZero(marked & ~box) / static_cast<double>(cv::countNonZero(~box));
  EXPECT_GT(covered, 0.8) << "box pixels inside the rectangles";
  EXPECT_LT(static_marked, 0.1) << "static pixels inside the rectangles";
  EXPECT_GE(report.regions, 1);
  EXPECT_GE(report.values.at("rectangles"), 1);
  EXPECT_GT(report.values.at("occlusion_boundaries"), 0);
  EXPECT_GT(report.dynamic_points.size(), 4u);
  // Every step reports its time.
  for (const char* k : {"disparity_ms", "corners_ms", "flow_ms", "fmatrix_ms", "rois_ms", "slic_ms",
                        "planes_ms", "boundaries_ms", "rectangles_ms", "total_ms"})
    EXPECT_TRUE(report.values.count(k)) << k;

  // Most dynamic points lie on the box, most static ones off it.
  int on_box = 0;
  for (const cv::Point2f& p : report.dynamic_points) on_box += box.at<uchar>(cvRound(p.y), cvRound(p.x)) ? 1 : 0;
  EXPECT_GT(on_box, 0.7 * report.dynamic_points.size());
}

TEST_F(LiStageTest, FillsDepthFromTheDisparity) {
  FrameData cur = *pair_->cur;
  Context ctx = stereo_context(calib_, cur, nullptr, cv::Mat());
  LiStage stage;
  StageReport report;
  stage.process(ctx, report);
  // No previous frame: nothing marked, but the depth is there for the others.
  EXPECT_EQ(report.values.at("skipped_no_previous"), 1);
  EXPECT_EQ(cv::countNonZero(ctx.dynamic), 0);
  ASSERT_FALSE(cur.depth.empty());
  ASSERT_EQ(cur.depth.type(), CV_32FC1);
  // Against the rendered depth: the valid pixels are mostly within 5 %.
  int valid = 0, good = 0;
  for (int y = 0; y < cur.depth.rows; y += 4)
    for (int x = 0; x < cur.depth.cols; x += 4) {
      const float z = cur.depth.at<float>(y, x), t = pair_->cur_view.depth.at<float>(y, x);
      if (!(z > 0) || !(t > 0)) continue;
      ++valid;
      good += std::abs(z - t) < 0.05 * t ? 1 : 0;
    }
  EXPECT_GT(valid, 0.5 * (cur.depth.total() / 16));
  EXPECT_GT(good, 0.85 * valid);
}

TEST_F(LiStageTest, DegenerateInputMarksNothing) {
  LiStage stage;
  {
    FrameData cur = *pair_->cur;
    cur.right = cv::Mat();
    Context ctx = stereo_context(calib_, cur, pair_->prev, cv::Mat());
    StageReport report;
    stage.process(ctx, report);
    EXPECT_EQ(report.values.at("skipped_no_right"), 1);
    EXPECT_EQ(cv::countNonZero(ctx.dynamic), 0);
  }
  {
    // A textureless pair: no corners to track.
    auto prev = std::make_shared<FrameData>();
    FrameData cur;
    prev->grey = cv::Mat(480, 640, CV_8UC1, cv::Scalar(128));
    prev->right = prev->grey.clone();
    cur.grey = prev->grey.clone();
    cur.right = prev->grey.clone();
    Context ctx = stereo_context(calib_, cur, prev, cv::Mat());
    StageReport report;
    stage.process(ctx, report);
    EXPECT_EQ(report.values.at("too_few_points"), 1);
    EXPECT_EQ(cv::countNonZero(ctx.dynamic), 0);
  }
  {
    // A previous frame of another size.
    auto prev = std::make_shared<FrameData>();
    prev->grey = cv::Mat(240, 320, CV_8UC1, cv::Scalar(128));
    FrameData cur = *pair_->cur;
    Context ctx = stereo_context(calib_, cur, prev, cv::Mat());
    StageReport report;
    stage.process(ctx, report);
    EXPECT_EQ(report.values.at("skipped_previous_mismatch"), 1);
  }
  {
    FrameData cur;
    cur.grey = cv::Mat(480, 640, CV_32FC1, cv::Scalar(0));
    Context ctx = stereo_context(calib_, cur, pair_->prev, cv::Mat());
    StageReport report;
    stage.process(ctx, report);
    EXPECT_EQ(report.values.at("skipped_bad_input"), 1);
  }
  {
    FrameData cur = *pair_->cur;
    Context ctx = stereo_context(nullptr, cur, pair_->prev, cv::Mat());
    StageReport report;
    stage.process(ctx, report);
    EXPECT_EQ(report.values.at("skipped_no_calibration"), 1);
  }
  EXPECT_TRUE(stage.supports(Sensor::kStereo));
  EXPECT_FALSE(stage.supports(Sensor::kMono));
  EXPECT_FALSE(stage.supports(Sensor::kRGBD));
  EXPECT_FALSE(stage.needs_motion_cues());
  EXPECT_EQ(stage.name(), "li");
}

// keep_frames (ours): a rectangle found on the moving box in two frames
// (keep_min_hits) stays marked while later frames find nothing (here the
// same image again: no motion at all), for keep_frames frames. Found in one
// frame only, after a reset, or with the paper's 0: nothing is carried.
TEST_F(LiStageTest, KeepsAFoundRectangleForKeepFrames) {
  const cv::Mat box = pair_->cur_view.object == dynaorb::test::li::kMoverIndex;
  const double box_px = cv::countNonZero(box);
  const auto still = std::make_shared<const FrameData>(*pair_->cur);
  struct Out {
    double box_covered = 0;
    int marked = 0;
    StageReport report;
  };
  auto run = [&](LiStage& stage, std::shared_ptr<const FrameData> prev) {
    FrameData cur = *pair_->cur;
    Context ctx = stereo_context(calib_, cur, std::move(prev), cv::Mat::zeros(cur.grey.size(), CV_8UC1));
    Out out;
    stage.process(ctx, out.report);
    out.marked = cv::countNonZero(ctx.dynamic);
    out.box_covered = cv::countNonZero(box & (ctx.dynamic != 0)) / box_px;
    return out;
  };
  LiOptions o;
  o.keep_frames = 2;
  LiStage stage(o);
  const Out found = run(stage, pair_->prev);
  ASSERT_GE(found.report.values.at("rectangles"), 1);
  ASSERT_GT(found.box_covered, 0.8);
  EXPECT_EQ(run(stage, still).marked, 0) << "found in one frame only";
  run(stage, pair_->prev);
  run(stage, pair_->prev);  // found in two frames in a row
  for (int frame = 1; frame <= 2; ++frame) {
    const Out carried = run(stage, still);
    EXPECT_EQ(carried.report.values.count("rectangles") ? carried.report.values.at("rectangles") : 0, 0) << frame;
    EXPECT_GE(carried.report.values.at("kept_rectangles"), 1) << frame;
    EXPECT_GT(carried.box_covered, 0.8) << frame;  // no flow: it stays where it was
    EXPECT_GE(carried.report.regions, 1) << frame;
  }
  EXPECT_EQ(run(stage, still).marked, 0) << "older than keep_frames";

  run(stage, pair_->prev);
  run(stage, pair_->prev);
  stage.reset();
  EXPECT_EQ(run(stage, still).marked, 0) << "reset forgets the rectangles";

  LiStage paper;  // keep_frames 0
  run(paper, pair_->prev);
  run(paper, pair_->prev);
  const Out next = run(paper, still);
  EXPECT_EQ(next.marked, 0);
  EXPECT_EQ(next.report.values.count("kept_rectangles"), 0u);
}

TEST(LiOptions, ReadKeepsDefaultsAndRejectsBadValues) {
  cv::FileStorage fs("%YAML:1.0\nli:\n  alpha_epi: 2.5\n  min_cluster_points: 7\n  fill_occlusions: false\n",
                     cv::FileStorage::READ | cv::FileStorage::MEMORY);
  LiOptions o;
  o.read(fs["li"]);
  EXPECT_DOUBLE_EQ(o.alpha_epi, 2.5);
  EXPECT_EQ(o.min_cluster_points, 7);
  EXPECT_FALSE(o.fill_occlusions);
  EXPECT_DOUBLE_EQ(o.beta_epi, LiOptions().beta_epi);
  EXPECT_DOUBLE_EQ(o.lambda_occ, 15.0);

  cv::FileStorage bad("%YAML:1.0\nli:\n  min_cluster_points: many\n", cv::FileStorage::READ | cv::FileStorage::MEMORY);
  LiOptions b;
  EXPECT_THROW(b.read(bad["li"]), InputError);
  cv::FileStorage order("%YAML:1.0\nli:\n  lambda_hinge: 20.0\n", cv::FileStorage::READ | cv::FileStorage::MEMORY);
  LiOptions c;
  EXPECT_THROW(c.read(order["li"]), InputError);  // eq. 11 needs lambda_occ > lambda_hinge
  for (const char* text : {"li: {keep_frames: -1}", "li: {keep_covered_fraction: 0}",
                           "li: {keep_covered_fraction: 1.5}", "li: {keep_min_hits: 0}", "li: {alpha_epi: .nan}",
                           "li: {beta_epi: .inf}", "li: {t_disp: .nan}", "li: {sgbm_block_size: 4}",
                           "li: {lk_forward_backward_max: -1}", "li: {lambda_pen: .nan}",
                           "li: {foreground_margin_px: .nan}", "li: {foreground_margin_px: -2}",
                           "li: {foreground_band_px: -1}", "li: {foreground_only: maybe}"}) {
    cv::FileStorage f(std::string("%YAML:1.0\n") + text + "\n", cv::FileStorage::READ | cv::FileStorage::MEMORY);
    LiOptions d;
    EXPECT_THROW(d.read(f["li"]), InputError) << text;
  }
  // The message names the key, its value and the rule, as every stage's.
  cv::FileStorage negative("%YAML:1.0\nli: {alpha_epi: -1}\n", cv::FileStorage::READ | cv::FileStorage::MEMORY);
  try {
    LiOptions().read(negative["li"]);
    ADD_FAILURE() << "a negative alpha_epi passed";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()),
              "Dynamic.li option 'alpha_epi' is -1; it must be a finite number >= 0 (0: no fixed part in eq. 3)");
  }
}

}  // namespace
}  // namespace dynaorb::dynamic
