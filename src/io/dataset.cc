#include "dynaorb/io/dataset.h"

#include <opencv2/imgcodecs.hpp>

#include "dataset_util.h"
#include "dynaorb/io/errors.h"

namespace dynaorb {

std::unique_ptr<DataProvider> open_dataset(const std::string& kind, const std::string& path,
                                           const DatasetOptions& options) {
  if (kind == "tum") return open_tum(path, options);
  if (kind == "kitti") return open_kitti(path, options);
  if (kind == "euroc") return open_euroc(path, options);
  throw InputError("unknown dataset kind '" + kind + "' (expected tum, kitti or euroc)");
}

namespace io {

void require_file(const fs::path& file, const std::string& listed_in, int line) {
  std::error_code ec;
  if (!fs::is_regular_file(file, ec))
    throw InputError(listed_in, line, "missing image " + file.string());
}

cv::Mat load_image(const fs::path& file, int imread_flags, const std::string& listed_in, int line) {
  require_file(file, listed_in, line);
  cv::Mat image;
  try {
    image = cv::imread(file.string(), imread_flags);
  } catch (const cv::Exception& e) {
    throw InputError(file.string(), 0, "cannot decode image (" + e.msg + ")");
  }
  if (image.empty())
    throw InputError(file.string(), 0,
                     "cannot decode image: corrupt or not an image (listed in " + listed_in + ":" +
                         std::to_string(line) + ")");
  return image;
}

void require_same_size(const cv::Mat& a, const std::string& a_path, const cv::Mat& b,
                       const std::string& b_path) {
  if (a.size() != b.size())
    throw InputError(b_path, 0,
                     "image size " + std::to_string(b.cols) + "x" + std::to_string(b.rows) +
                         " differs from " + std::to_string(a.cols) + "x" + std::to_string(a.rows) +
                         " of " + a_path);
}

Sensor choose_sensor(const DatasetOptions& options, Sensor richest, bool allow_stereo,
                     bool allow_rgbd, const std::string& what) {
  Sensor s = options.sensor.value_or(richest);
  if ((s == Sensor::kStereo && !allow_stereo) || (s == Sensor::kRGBD && !allow_rgbd))
    throw InputError(what + " has no data for sensor '" + to_string(s) + "'");
  return s;
}

bool has_settings_file(const fs::path& root) {
  std::error_code ec;
  return fs::is_regular_file(root / "settings.yaml", ec);
}

}  // namespace io
}  // namespace dynaorb
