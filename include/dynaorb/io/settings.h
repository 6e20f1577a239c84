#pragma once
// Camera and extractor settings. Reads the ORB-SLAM2 settings YAML as is
// (Camera.fx ..., Camera.bf, ThDepth, DepthMapFactor, ORBextractor.*, and the
// stereo rectification blocks LEFT.* / RIGHT.*); new keys extend it.
#include <opencv2/core.hpp>
#include <optional>
#include <string>

#include "dynaorb/core/sensor.h"

namespace dynaorb {

struct CameraSettings {
  double fx = 0, fy = 0, cx = 0, cy = 0;
  cv::Mat dist = cv::Mat::zeros(1, 4, CV_64F);  // k1 k2 p1 p2 [k3]
  int width = 0, height = 0;                    // 0: not given, taken from the first frame
  double fps = 30.0;
  bool rgb = true;                              // Camera.RGB: colour order of input images
  std::optional<double> bf;                     // Camera.bf = baseline * fx (stereo, RGB-D)
  std::optional<double> th_depth;               // ThDepth, in baselines (stereo, RGB-D)
  std::optional<double> depth_map_factor;       // DepthMapFactor (RGB-D)

  bool has_distortion() const;
  double baseline() const { return bf ? *bf / fx : 0.0; }
};

struct ExtractorSettings {
  int n_features = 1000;
  double scale_factor = 1.2;
  int n_levels = 8;
  int ini_th_fast = 20;
  int min_th_fast = 7;
};

// ORB-SLAM2's LEFT./RIGHT. blocks: raw image -> rectified image maps.
struct StereoRectification {
  int width = 0, height = 0;
  cv::Mat K_l, D_l, R_l, P_l;
  cv::Mat K_r, D_r, R_r, P_r;
  bool enabled() const { return !K_l.empty(); }
};

struct Settings {
  std::string source;  // file the settings came from ("" when built in code)
  CameraSettings camera;
  ExtractorSettings extractor;
  StereoRectification rectification;

  // Throws InputError naming the file and key when the file is missing, not
  // YAML, lacks a required key or holds a value of the wrong type.
  static Settings load(const std::string& path);
  void save(const std::string& path) const;

  // Checks the keys a sensor needs (Camera.bf and ThDepth for stereo and RGB-D,
  // DepthMapFactor for RGB-D) and value ranges; throws InputError naming them.
  void validate(Sensor sensor) const;

  std::string summary() const;
};

}  // namespace dynaorb
