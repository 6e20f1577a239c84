// The DM-SLAM, STDyn-SLAM and DDL-SLAM stages' options: each value out of
// range is refused by name, from code (validate, the stage's constructor)
// and from a preset (at load, the file named); the values that mean "off"
// are accepted.
#include <gtest/gtest.h>
#include <cstdio>
#include <fstream>
#include <functional>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "dynaorb/dynamic/ddl_stage.h"
#include "dynaorb/dynamic/dm_stage.h"
#include "dynaorb/dynamic/dynamic_filter.h"
#include "dynaorb/dynamic/stdyn_stage.h"
#include "dynaorb/io/errors.h"

namespace dynaorb::dynamic {
namespace {

const double kNan = std::numeric_limits<double>::quiet_NaN();
const double kInf = std::numeric_limits<double>::infinity();

template <class Options>
using Changes = std::vector<std::pair<std::string, std::function<void(Options&)>>>;

// Every change must be refused by validate() with "<section> option '<key>'".
template <class Options>
void expect_refused(const std::string& section, const Changes<Options>& bad) {
  for (const auto& [key, change] : bad) {
    Options o;
    change(o);
    try {
      o.validate();
      ADD_FAILURE() << section << "." << key << " accepted";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(section + " option '" + key + "'"), std::string::npos) << e.what();
    }
  }
}

TEST(StageOptions, DmOutOfRangeIsRefusedByName) {
  EXPECT_NO_THROW(DmOptions().validate());
  DmOptions paper;
  paper.min_dynamic_offset_px = 0;  // eq. 8 alone
  paper.region_dynamic_fraction = 1;
  EXPECT_NO_THROW(paper.validate());
  expect_refused<DmOptions>(
      "Dynamic.dm", {
                        {"min_static_points", [](DmOptions& o) { o.min_static_points = 0; }},
                        {"min_dynamic_offset_px", [](DmOptions& o) { o.min_dynamic_offset_px = -0.5; }},
                        {"min_dynamic_offset_px", [](DmOptions& o) { o.min_dynamic_offset_px = kNan; }},
                        {"epipolar_threshold_px", [](DmOptions& o) { o.epipolar_threshold_px = 0; }},
                        {"epipolar_threshold_px", [](DmOptions& o) { o.epipolar_threshold_px = kInf; }},
                        {"region_dynamic_fraction", [](DmOptions& o) { o.region_dynamic_fraction = 0; }},
                        {"region_dynamic_fraction_mono", [](DmOptions& o) { o.region_dynamic_fraction_mono = 1.5; }},
                        {"min_region_points", [](DmOptions& o) { o.min_region_points = 0; }},
                        {"few_points_policy", [](DmOptions& o) { o.few_points_policy = "sometimes"; }},
                        {"keep_moving_frames_mono", [](DmOptions& o) { o.keep_moving_frames_mono = -1; }},
                        {"keep_moving_overlap", [](DmOptions& o) { o.keep_moving_overlap = kNan; }},
                    });
  DmOptions bad;
  bad.epipolar_threshold_px = -1;
  EXPECT_THROW(DmStage{bad}, InputError);
}

TEST(StageOptions, StdynOutOfRangeIsRefusedByName) {
  EXPECT_NO_THROW(StdynOptions().validate());
  StdynOptions off;
  off.patch_max_abs_diff = 0;  // no patch check
  off.min_dynamic_ratio = 0;   // the released codes' one-point rule
  off.object_search_radius_px = 0;
  EXPECT_NO_THROW(off.validate());
  expect_refused<StdynOptions>(
      "Dynamic.stdyn",
      {
          {"epipolar_threshold_px", [](StdynOptions& o) { o.epipolar_threshold_px = kNan; }},
          {"f_ransac_threshold_px", [](StdynOptions& o) { o.f_ransac_threshold_px = 0; }},
          {"f_ransac_confidence", [](StdynOptions& o) { o.f_ransac_confidence = 1; }},
          {"f_ransac_iterations", [](StdynOptions& o) { o.f_ransac_iterations = 0; }},
          {"f_method", [](StdynOptions& o) { o.f_method = "lmeds"; }},
          {"min_points", [](StdynOptions& o) { o.min_points = 7; }},
          {"edge_margin_px", [](StdynOptions& o) { o.edge_margin_px = -1; }},
          {"patch_max_abs_diff", [](StdynOptions& o) { o.patch_max_abs_diff = kNan; }},
          {"min_dynamic_points", [](StdynOptions& o) { o.min_dynamic_points = 0; }},
          {"min_dynamic_ratio", [](StdynOptions& o) { o.min_dynamic_ratio = 1.2; }},
          {"object_search_radius_px", [](StdynOptions& o) { o.object_search_radius_px = -15; }},
          {"keep_moving_frames", [](StdynOptions& o) { o.keep_moving_frames = -1; }},
          {"keep_moving_overlap", [](StdynOptions& o) { o.keep_moving_overlap = kNan; }},
          {"keep_moving_overlap", [](StdynOptions& o) { o.keep_moving_overlap = 1.5; }},
          {"no_labels_point_radius_px", [](StdynOptions& o) { o.no_labels_point_radius_px = 0; }},
          {"movable_labels", [](StdynOptions& o) { o.movable_labels = {15, 300}; }},
      });
  StdynOptions bad;
  bad.min_points = 4;
  EXPECT_THROW(StdynStage{bad}, InputError);
}

TEST(StageOptions, DdlOutOfRangeIsRefusedByName) {
  EXPECT_NO_THROW(DdlOptions().validate());
  DdlOptions off;
  off.max_depth_m = 0;           // no limit
  off.confirm_min_zncc = -1;     // no texture test
  off.confirm_blur_sigma_px = 0;
  off.grow_max_from_seed_m = 0;  // no limit
  EXPECT_NO_THROW(off.validate());
  expect_refused<DdlOptions>(
      "Dynamic.ddl", {
                         {"reference_keyframes", [](DdlOptions& o) { o.reference_keyframes = 0; }},
                         {"min_overlap", [](DdlOptions& o) { o.min_overlap = -0.1; }},
                         {"parallax_threshold_deg", [](DdlOptions& o) { o.parallax_threshold_deg = 180; }},
                         {"parallax_threshold_deg", [](DdlOptions& o) { o.parallax_threshold_deg = kNan; }},
                         {"depth_threshold_m", [](DdlOptions& o) { o.depth_threshold_m = 0; }},
                         {"max_depth_m", [](DdlOptions& o) { o.max_depth_m = -1; }},
                         {"depth_search_radius_px", [](DdlOptions& o) { o.depth_search_radius_px = -1; }},
                         {"refine_reprojection_px", [](DdlOptions& o) { o.refine_reprojection_px = kNan; }},
                         {"refine_min_inliers", [](DdlOptions& o) { o.refine_min_inliers = 3; }},
                         {"confirm_min_zncc", [](DdlOptions& o) { o.confirm_min_zncc = 1.5; }},
                         {"confirm_patch_radius_px", [](DdlOptions& o) { o.confirm_patch_radius_px = 0; }},
                         {"grow_max_step_inv_depth", [](DdlOptions& o) { o.grow_max_step_inv_depth = 0; }},
                         {"dilation_px", [](DdlOptions& o) { o.dilation_px = -2; }},
                     });
  DdlOptions bad;
  bad.reference_keyframes = 0;
  EXPECT_THROW(DdlStage{bad}, InputError);
}

// A preset is refused when it is loaded, with the file and the key named.
TEST(StageOptions, PresetWithAValueOutOfRangeIsRefusedAtLoad) {
  const std::vector<std::pair<std::string, std::string>> presets = {
      {"Dynamic.stages: [semantic, dm]\nDynamic.dm:\n  region_dynamic_fraction: 0\n", "'region_dynamic_fraction' is 0"},
      {"Dynamic.stages: [semantic, stdyn]\nDynamic.stdyn:\n  f_ransac_confidence: 1.5\n",
       "'f_ransac_confidence' is 1.5"},
      {"Dynamic.stages: [semantic, ddl]\nDynamic.ddl:\n  parallax_threshold_deg: -30\n",
       "'parallax_threshold_deg' is -30"},
  };
  for (const auto& [yaml, message] : presets) {
    try {
      DynamicFilterOptions::parse(yaml, "mine.yaml");
      ADD_FAILURE() << yaml << " accepted";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("mine.yaml"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(message), std::string::npos) << e.what();
    }
  }
}

// A preset file without the `%YAML:1.0` line loads (users write YAML by
// hand); a bad value in it is refused with the file's path.
TEST(StageOptions, PresetFileWithoutTheYamlLineLoads) {
  const std::string path = ::testing::TempDir() + "/stage_options_no_header.yaml";
  std::ofstream(path) << "Dynamic.stages: [semantic, dm]\nDynamic.dm:\n  epipolar_threshold_px: 2\n";
  const DynamicFilterOptions o = DynamicFilterOptions::load(path);
  EXPECT_EQ(o.stages, (std::vector<std::string>{"semantic", "dm"}));
  std::ofstream(path) << "Dynamic.stages: [semantic, dm]\nDynamic.dm:\n  min_region_points: 0\n";
  try {
    DynamicFilterOptions::load(path);
    ADD_FAILURE() << "min_region_points 0 accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("'min_region_points' is 0"), std::string::npos) << e.what();
  }
  std::remove(path.c_str());
}

}  // namespace
}  // namespace dynaorb::dynamic
