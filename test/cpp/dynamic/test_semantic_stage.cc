#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include "dynaorb/dynamic/semantic_stage.h"
#include "dynaorb/io/errors.h"

namespace dynaorb::dynamic {
namespace {

constexpr int kPerson = 15, kCar = 7, kChair = 9;  // PASCAL VOC ids

// A frame with a person (a 40x60 box at (100, 80)) and a chair.
FrameData labelled_frame() {
  FrameData f;
  f.grey = cv::Mat(240, 320, CV_8UC1, cv::Scalar(128));
  f.labels = cv::Mat::zeros(240, 320, CV_8UC1);
  f.labels(cv::Rect(100, 80, 40, 60)).setTo(kPerson);
  f.labels(cv::Rect(220, 150, 30, 30)).setTo(kChair);
  return f;
}

SemanticOptions options(const std::string& yaml) {
  cv::FileStorage fs("%YAML:1.0\nDynamic.semantic: " + yaml + "\n",
                     cv::FileStorage::READ | cv::FileStorage::MEMORY | cv::FileStorage::FORMAT_YAML);
  SemanticOptions o;
  o.read(fs["Dynamic.semantic"]);
  return o;
}

StageReport run(SemanticStage& stage, FrameData& f, cv::Mat& dynamic) {
  Context ctx{Sensor::kRGBD, nullptr, f, nullptr, cv::Mat::zeros(f.grey.size(), CV_8UC1), nullptr, nullptr,
              std::nullopt, nullptr, {}};
  StageReport report;
  stage.process(ctx, report);
  dynamic = ctx.dynamic;
  return report;
}

TEST(SemanticStage, WidenByDiscIsTheExactDistanceTransformsDisc) {
  // The rule: pixels the exact Euclidean distance transform puts within the radius.
  const auto by_transform = [](const cv::Mat& mask, int radius) {
    cv::Mat dist;
    cv::distanceTransform(mask == 0, dist, cv::DIST_L2, cv::DIST_MASK_PRECISE, CV_32F);
    return cv::Mat(dist <= static_cast<float>(radius));
  };
  cv::RNG rng(7);
  for (int scene = 0; scene < 60; ++scene) {
    cv::Mat mask = cv::Mat::zeros(rng.uniform(1, 120), rng.uniform(1, 400), CV_8UC1);
    for (int k = rng.uniform(0, 6); k > 0; --k) {  // dots, boxes and discs
      const cv::Point c(rng.uniform(0, mask.cols), rng.uniform(0, mask.rows));
      const int shape = rng.uniform(0, 3);
      if (shape == 0) mask.at<unsigned char>(c) = rng.uniform(1, 256);
      else if (shape == 1) cv::rectangle(mask, cv::Rect(c, cv::Size(rng.uniform(1, 30), rng.uniform(1, 30))), 255, -1);
      else cv::circle(mask, c, rng.uniform(1, 20), 200, -1);
    }
    for (int radius : {1, 2, 3, 7, 15, 16, 40, 254, 255, 300, 1 << 20}) {
      const cv::Mat got = widen_by_disc(mask, radius);
      const cv::Mat want = cv::countNonZero(mask) ? by_transform(mask, radius) : cv::Mat::zeros(mask.size(), CV_8UC1);
      ASSERT_EQ(cv::countNonZero(got != want), 0) << "scene " << scene << ", radius " << radius;
    }
    ASSERT_EQ(cv::countNonZero(widen_by_disc(mask, 0) != (mask != 0)), 0);
  }
}

TEST(SemanticStage, ClassSetsOfThePapers) {
  EXPECT_EQ(voc_movable_classes().size(), 14u);   // DynaSLAM / STDyn / DDL
  EXPECT_EQ(coco_movable_classes().size(), 20u);  // DM-SLAM Sec. 3.2.1
  EXPECT_EQ(cityscapes_movable_classes().size(), 8u);
  // VOC: person and car are movable, chair (9), bottle (5) and sofa (18) are not.
  const auto& voc = voc_movable_classes();
  for (int id : {kPerson, kCar}) EXPECT_NE(std::find(voc.begin(), voc.end(), id), voc.end());
  for (int id : {5, kChair, 18}) EXPECT_EQ(std::find(voc.begin(), voc.end(), id), voc.end());
  EXPECT_EQ(options("{classes: coco}").ids, coco_movable_classes());
  EXPECT_EQ(options("{classes: cityscapes}").ids, cityscapes_movable_classes());
  EXPECT_EQ(options("{classes: [15, 300]}").ids, (std::vector<int>{15, 300}));
}

TEST(SemanticStage, DropMarksMovableClassesWithTheirMargin) {
  SemanticStage stage(options("{margin: 10, policy: drop}"));
  FrameData f = labelled_frame();
  cv::Mat dynamic;
  const StageReport r = run(stage, f, dynamic);
  ASSERT_FALSE(f.candidates.empty());
  EXPECT_EQ(cv::countNonZero(f.candidates != dynamic), 0);  // drop: the candidates are dynamic
  // The person box and 10 px around it; not 11 px away, not the chair.
  EXPECT_EQ(dynamic.at<uchar>(80 + 30, 100 + 20), 255);
  EXPECT_EQ(dynamic.at<uchar>(80 + 30, 100 - 10), 255);
  EXPECT_EQ(dynamic.at<uchar>(80 + 30, 100 - 11), 0);
  EXPECT_EQ(dynamic.at<uchar>(80 + 60 - 1 + 10, 100 + 20), 255);
  EXPECT_EQ(dynamic.at<uchar>(80 + 60 - 1 + 11, 100 + 20), 0);
  // A disc, not a square: the corner's diagonal neighbour at (7, 7) is within 10 px, (8, 8) is not.
  EXPECT_EQ(dynamic.at<uchar>(80 - 7, 100 - 7), 255);
  EXPECT_EQ(dynamic.at<uchar>(80 - 8, 100 - 8), 0);
  EXPECT_EQ(dynamic.at<uchar>(165, 235), 0);  // chair
  EXPECT_EQ(r.regions, 1);
  EXPECT_NEAR(r.values.at("candidate_fraction"), cv::countNonZero(dynamic) / (320.0 * 240.0), 1e-12);
}

TEST(SemanticStage, StaticUntilProvenOnlySetsCandidates) {
  SemanticStage stage(options("{margin: 0, policy: static_until_proven}"));
  FrameData f = labelled_frame();
  cv::Mat dynamic;
  const StageReport r = run(stage, f, dynamic);
  EXPECT_EQ(cv::countNonZero(dynamic), 0);
  EXPECT_EQ(cv::countNonZero(f.candidates), 40 * 60);  // margin 0: exactly the person
  EXPECT_EQ(r.regions, 0);
  EXPECT_EQ(r.values.at("candidate_regions"), 1);
}

// With no previous frame nothing can be proven to move: static_until_proven
// leaves the candidates of such a frame static (DM-SLAM), or drops them with
// drop_unchecked_<sensor>; drop_unchecked sets stereo's and RGB-D's, which
// their own keys override.
TEST(SemanticStage, UncheckedFrameDropsItsCandidatesWhenAsked) {
  struct Case {
    std::string keys;
    bool mono, stereo, rgbd;  // which sensors drop
  };
  for (const Case& c : {Case{"", false, false, false}, Case{", drop_unchecked_mono: 1", true, false, false},
                        Case{", drop_unchecked: 1", false, true, true},
                        Case{", drop_unchecked_rgbd: 1", false, false, true},
                        Case{", drop_unchecked_stereo: 1", false, true, false},
                        Case{", drop_unchecked: 1, drop_unchecked_stereo: 0", false, false, true},
                        Case{", drop_unchecked_rgbd: 1, drop_unchecked: 0", false, false, true}}) {
    const std::string yaml = "{margin: 0, policy: static_until_proven" + c.keys + "}";
    for (Sensor s : {Sensor::kMono, Sensor::kStereo, Sensor::kRGBD}) {
      SemanticStage stage(options(yaml));
      FrameData f = labelled_frame();
      auto previous = std::make_shared<FrameData>(labelled_frame());
      const bool drops = s == Sensor::kMono ? c.mono : s == Sensor::kStereo ? c.stereo : c.rgbd;
      for (bool with_previous : {false, true}) {
        Context ctx{s, nullptr, f, with_previous ? previous : nullptr, cv::Mat::zeros(f.grey.size(), CV_8UC1),
                    nullptr, nullptr, std::nullopt, nullptr, {}};
        StageReport r;
        stage.process(ctx, r);
        const bool dropped = !with_previous && drops;
        EXPECT_EQ(cv::countNonZero(ctx.dynamic), dropped ? 40 * 60 : 0) << yaml << " " << to_string(s);
        EXPECT_EQ(r.values.count("unchecked_dropped"), dropped ? 1u : 0u);
        EXPECT_EQ(r.regions, dropped ? 1 : 0);
        EXPECT_EQ(cv::countNonZero(f.candidates), 40 * 60);
      }
    }
  }
}

TEST(SemanticStage, ExplicitIdsAndSixteenBitLabels) {
  SemanticStage stage(options("{classes: [9, 1000], margin: 0}"));
  FrameData f = labelled_frame();
  f.labels.convertTo(f.labels, CV_16U);
  f.labels(cv::Rect(0, 0, 5, 5)).setTo(1000);
  cv::Mat dynamic;
  run(stage, f, dynamic);
  EXPECT_EQ(cv::countNonZero(dynamic), 30 * 30 + 25);  // the chair and the id-1000 corner, not the person
  // The label source's own set replaces the configured one.
  stage.set_movable_classes({kPerson});
  run(stage, f, dynamic);
  EXPECT_EQ(cv::countNonZero(dynamic), 40 * 60);
}

TEST(SemanticStage, NoOrBadLabelsMarkNothing) {
  SemanticStage stage;
  FrameData f = labelled_frame();
  f.labels.release();
  cv::Mat dynamic;
  StageReport r = run(stage, f, dynamic);
  EXPECT_EQ(r.values.at("skipped_no_labels"), 1);
  EXPECT_TRUE(f.candidates.empty());
  EXPECT_EQ(cv::countNonZero(dynamic), 0);
  f.labels = cv::Mat::zeros(10, 10, CV_8UC1);
  r = run(stage, f, dynamic);
  EXPECT_EQ(r.values.at("skipped_bad_labels"), 1);
  f.labels = cv::Mat::zeros(240, 320, CV_32FC1);
  r = run(stage, f, dynamic);
  EXPECT_EQ(r.values.at("skipped_bad_labels"), 1);
}

TEST(SemanticStage, OptionErrorsNameTheKey) {
  auto message = [](const std::string& yaml) {
    try {
      options(yaml);
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(message("{classes: kitti}").find("Dynamic.semantic.classes"), std::string::npos);
  EXPECT_NE(message("{classes: [person]}").find("Dynamic.semantic.classes"), std::string::npos);
  EXPECT_NE(message("{margin: wide}").find("Dynamic.semantic.margin"), std::string::npos);
  EXPECT_NE(message("{margin: -1}").find("Dynamic.semantic.margin"), std::string::npos);
  EXPECT_NE(message("{policy: maybe}").find("Dynamic.semantic.policy"), std::string::npos);
  EXPECT_NE(message("{drop_unchecked: maybe}").find("Dynamic.semantic.drop_unchecked"), std::string::npos);
  EXPECT_NE(message("{drop_unchecked_rgbd: 0.5}").find("Dynamic.semantic.drop_unchecked_rgbd"), std::string::npos);
  EXPECT_EQ(message("{policy: static_until_proven}"), "no error");
}

}  // namespace
}  // namespace dynaorb::dynamic
