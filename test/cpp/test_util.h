#pragma once
// Helpers for the gtests: the shared data folder and scratch folders.
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <gtest/gtest.h>
#include <random>
#include <string>

#include "dynaorb/io/errors.h"
#include "dynaorb/io/settings.h"

namespace dynaorb::test {

namespace fs = std::filesystem;

// A 640x480 RGB-D camera (fx 500, TUM's bf, ThDepth and DepthMapFactor) for
// System tests on images made in the test.
inline Settings rgbd_settings() {
  Settings s;
  s.camera.fx = s.camera.fy = 500;
  s.camera.cx = 320;
  s.camera.cy = 240;
  s.camera.width = 640;
  s.camera.height = 480;
  s.camera.bf = 40;
  s.camera.th_depth = 40;
  s.camera.depth_map_factor = 5000;
  return s;
}

// The message of the InputError an Options' validate() throws once `change`
// has been applied to the defaults; "" when it passes.
template <typename Options, typename Change>
std::string validation_refusal(Change change) {
  Options o;
  change(o);
  try {
    o.validate();
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

// ../shared/data beside the repository, or $DYNAORB_SHARED/data.
inline fs::path shared_data() {
  if (const char* env = std::getenv("DYNAORB_SHARED")) return fs::path(env) / "data";
  return fs::path(DYNAORB_SOURCE_DIR).parent_path() / "shared" / "data";
}

#define DYNAORB_REQUIRE_SHARED()                                                        \
  do {                                                                                  \
    if (!std::filesystem::is_directory(::dynaorb::test::shared_data()))                 \
      GTEST_SKIP() << "shared data not found at " << ::dynaorb::test::shared_data();   \
  } while (0)

// A fresh folder under the system temp dir, removed when the object dies.
class ScratchDir {
 public:
  ScratchDir() {
    std::random_device rd;
    path_ = fs::temp_directory_path() / ("dynaorb_test_" + std::to_string(rd()) + std::to_string(rd()));
    fs::create_directories(path_);
  }
  ~ScratchDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  const fs::path& path() const { return path_; }
  fs::path write(const std::string& name, const std::string& text) const {
    fs::path p = path_ / name;
    fs::create_directories(p.parent_path());
    std::ofstream(p) << text;
    return p;
  }

 private:
  fs::path path_;
};

// Copies a directory tree (small test data only).
inline void copy_tree(const fs::path& from, const fs::path& to) {
  fs::copy(from, to, fs::copy_options::recursive | fs::copy_options::overwrite_existing);
}

}  // namespace dynaorb::test
