#include <gtest/gtest.h>

#include "../test_util.h"
#include "dynaorb/io/errors.h"
#include "dynaorb/io/settings.h"

namespace dynaorb {
namespace {

using test::ScratchDir;

const char* kRgbdYaml = R"(%YAML:1.0
Camera.fx: 535.4
Camera.fy: 539.2
Camera.cx: 320.1
Camera.cy: 247.6
Camera.k1: 0.0
Camera.k2: 0.0
Camera.p1: 0.0
Camera.p2: 0.0
Camera.width: 640
Camera.height: 480
Camera.fps: 30.0
Camera.bf: 40.0
Camera.RGB: 1
ThDepth: 40.0
DepthMapFactor: 5000.0
ORBextractor.nFeatures: 1000
ORBextractor.scaleFactor: 1.2
ORBextractor.nLevels: 8
ORBextractor.iniThFAST: 20
ORBextractor.minThFAST: 7
)";

TEST(Settings, LoadsOrbSlam2Yaml) {
  ScratchDir dir;
  Settings s = Settings::load(dir.write("tum3.yaml", kRgbdYaml).string());
  EXPECT_DOUBLE_EQ(s.camera.fx, 535.4);
  EXPECT_DOUBLE_EQ(s.camera.cy, 247.6);
  EXPECT_EQ(s.camera.width, 640);
  EXPECT_DOUBLE_EQ(*s.camera.depth_map_factor, 5000.0);
  EXPECT_EQ(s.extractor.n_features, 1000);
  EXPECT_FALSE(s.camera.has_distortion());
  EXPECT_NO_THROW(s.validate(Sensor::kRGBD));
}

TEST(Settings, EveryShippedConfigLoads) {
  const test::fs::path config = test::fs::path(DYNAORB_SOURCE_DIR) / "config";
  int count = 0;
  for (const auto& entry : test::fs::directory_iterator(config)) {
    const std::string name = entry.path().filename().string();
    if (entry.path().extension() != ".yaml" || name.rfind("dynamic", 0) == 0) continue;
    SCOPED_TRACE(name);
    Settings s = Settings::load(entry.path().string());
    EXPECT_GT(s.camera.fx, 0);
    if (name.find("stereo") != std::string::npos || name.find("KITTI") != std::string::npos) {
      EXPECT_NO_THROW(s.validate(Sensor::kStereo));
    }
    if (name.find("TUM") != std::string::npos) {
      EXPECT_NO_THROW(s.validate(Sensor::kRGBD));
    }
    ++count;
  }
  EXPECT_GE(count, 8);
}

TEST(Settings, MissingKeyIsNamed) {
  ScratchDir dir;
  std::string text = kRgbdYaml;
  text.erase(text.find("Camera.fy"), std::string("Camera.fy: 539.2\n").size());
  const auto path = dir.write("bad.yaml", text).string();
  try {
    Settings::load(path);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("Camera.fy"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
  }
}

TEST(Settings, SensorSpecificKeysAreChecked) {
  ScratchDir dir;
  std::string text = kRgbdYaml;
  text.erase(text.find("DepthMapFactor"), std::string("DepthMapFactor: 5000.0\n").size());
  Settings s = Settings::load(dir.write("nodepth.yaml", text).string());
  EXPECT_NO_THROW(s.validate(Sensor::kStereo));
  try {
    s.validate(Sensor::kRGBD);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("DepthMapFactor"), std::string::npos) << e.what();
  }
}

TEST(Settings, WrongTypeAndBrokenFilesAreNamed) {
  ScratchDir dir;
  std::string text = kRgbdYaml;
  text.replace(text.find("535.4"), 5, "\"abc\"");
  EXPECT_THROW(Settings::load(dir.write("string.yaml", text).string()), InputError);
  EXPECT_THROW(Settings::load(dir.write("garbage.yaml", "%YAML:1.0\n: : [\n").string()), InputError);
  EXPECT_THROW(Settings::load((dir.path() / "absent.yaml").string()), InputError);
}

TEST(Settings, SaveLoadRoundTrip) {
  ScratchDir dir;
  Settings s = Settings::load(dir.write("a.yaml", kRgbdYaml).string());
  const auto out = (dir.path() / "b.yaml").string();
  s.save(out);
  Settings t = Settings::load(out);
  EXPECT_DOUBLE_EQ(t.camera.fy, s.camera.fy);
  EXPECT_DOUBLE_EQ(*t.camera.bf, *s.camera.bf);
  EXPECT_EQ(t.extractor.n_levels, s.extractor.n_levels);
}

}  // namespace
}  // namespace dynaorb
