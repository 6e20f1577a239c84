// LocalMapperOptions::validate and LoopCloserOptions::validate: the defaults
// pass, zero passes where it means "off", and a bad value of each kind is
// refused with an InputError that names the option.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>

#include "dynaorb/io/errors.h"
#include "dynaorb/loop/loop_closer.h"
#include "dynaorb/mapping/local_mapper.h"
#include "../test_util.h"

namespace dynaorb {
namespace {

using loop::LoopCloserOptions;
using mapping::LocalMapperOptions;

using test::validation_refusal;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

TEST(LocalMapperOptions, DefaultsAndOffValuesAreValid) {
  EXPECT_NO_THROW(LocalMapperOptions().validate());
  EXPECT_EQ(validation_refusal<LocalMapperOptions>([](auto& o) { o.min_found_ratio = 0; }), "");
  EXPECT_EQ(validation_refusal<LocalMapperOptions>([](auto& o) { o.min_observations_stereo = 0; }), "");
  EXPECT_EQ(validation_refusal<LocalMapperOptions>([](auto& o) { o.local_ba = false; }), "");
  EXPECT_EQ(validation_refusal<LocalMapperOptions>([](auto& o) { o.thread_nice = 0; }), "");
  // ORB-SLAM3's local BA: one pass of 10, no second pass.
  EXPECT_EQ(validation_refusal<LocalMapperOptions>([](auto& o) {
              o.ba_iterations_first = 10;
              o.ba_iterations_second = 0;
            }),
            "");
}

TEST(LocalMapperOptions, BadValuesAreRefusedByName) {
  EXPECT_EQ(validation_refusal<LocalMapperOptions>([](auto& o) { o.neighbors_stereo = 0; }),
            "local mapping option 'neighbors_stereo' is 0; it must be >= 1");
  EXPECT_EQ(validation_refusal<LocalMapperOptions>([](auto& o) { o.min_found_ratio = kNaN; }),
            "local mapping option 'min_found_ratio' is nan; it must be a ratio in [0, 1] (0: no point culled for it)");
  EXPECT_EQ(validation_refusal<LocalMapperOptions>([](auto& o) { o.redundant_ratio = 1.5; }),
            "local mapping option 'redundant_ratio' is 1.5; it must be in (0, 1]");
  EXPECT_EQ(validation_refusal<LocalMapperOptions>([](auto& o) { o.min_observations_mono = -1; }),
            "local mapping option 'min_observations_mono' is -1; it must be >= 0");
  EXPECT_EQ(validation_refusal<LocalMapperOptions>([](auto& o) { o.ba_threads = 0; }),
            "local mapping option 'ba_threads' is 0; it must be >= 1");
  EXPECT_EQ(validation_refusal<LocalMapperOptions>([](auto& o) { o.ba_iterations_first = 0; }),
            "local mapping option 'ba_iterations_first' is 0; it must be >= 1");
  EXPECT_EQ(validation_refusal<LocalMapperOptions>([](auto& o) { o.ba_iterations_second = -1; }),
            "local mapping option 'ba_iterations_second' is -1; it must be >= 0");
  EXPECT_NE(validation_refusal<LocalMapperOptions>([](auto& o) { o.thread_nice = 20; }).find("'thread_nice'"),
            std::string::npos);
}

TEST(LoopCloserOptions, DefaultsAreValid) {
  EXPECT_NO_THROW(LoopCloserOptions().validate());
  EXPECT_EQ(validation_refusal<LoopCloserOptions>([](auto& o) { o.min_map_keyframes = 0; }), "");
  EXPECT_EQ(validation_refusal<LoopCloserOptions>([](auto& o) { o.global_ba = false; }), "");
}

TEST(LoopCloserOptions, BadValuesAreRefusedByName) {
  EXPECT_EQ(validation_refusal<LoopCloserOptions>([](auto& o) { o.ransac.chi2 = -1; }),
            "loop closing option 'ransac.chi2' is -1; it must be a finite number > 0");
  EXPECT_EQ(validation_refusal<LoopCloserOptions>([](auto& o) { o.ransac.probability = 1; }),
            "loop closing option 'ransac.probability' is 1; it must be in (0, 1)");
  EXPECT_EQ(validation_refusal<LoopCloserOptions>([](auto& o) { o.ransac.min_inliers = 2; }),
            "loop closing option 'ransac.min_inliers' is 2; it must be >= 3");
  EXPECT_EQ(validation_refusal<LoopCloserOptions>([](auto& o) { o.bow_nn_ratio = kNaN; }),
            "loop closing option 'bow_nn_ratio' is nan; it must be in (0, 1]");
  EXPECT_EQ(validation_refusal<LoopCloserOptions>([](auto& o) { o.projection_radius = INFINITY; }),
            "loop closing option 'projection_radius' is inf; it must be a finite number > 0");
  EXPECT_EQ(validation_refusal<LoopCloserOptions>([](auto& o) { o.pose_graph_iterations = 0; }),
            "loop closing option 'pose_graph_iterations' is 0; it must be >= 1");
}

}  // namespace
}  // namespace dynaorb
