#include "dynaorb/io/settings.h"

#include <fstream>
#include <iomanip>
#include <sstream>

#include "dynaorb/io/errors.h"

namespace dynaorb {

namespace {

class Reader {
 public:
  explicit Reader(const std::string& path) : path_(path) {
    std::ifstream probe(path);
    if (!probe) throw InputError(path, 0, "settings file not found or not readable");
    try {
      fs_.open(path, cv::FileStorage::READ | cv::FileStorage::FORMAT_YAML);
    } catch (const cv::Exception& e) {
      throw InputError(path, 0, "not a valid OpenCV YAML settings file (" + e.msg + ")");
    }
    if (!fs_.isOpened()) throw InputError(path, 0, "not a valid OpenCV YAML settings file");
  }

  bool has(const std::string& key) const { return !fs_[key].empty() && !fs_[key].isNone(); }

  double number(const std::string& key) const {
    cv::FileNode node = fs_[key];
    if (node.empty() || node.isNone()) throw InputError(path_, 0, "missing key '" + key + "'");
    if (!node.isReal() && !node.isInt())
      throw InputError(path_, 0, "key '" + key + "' must be a number");
    return static_cast<double>(node);
  }

  std::optional<double> optional_number(const std::string& key) const {
    if (!has(key)) return std::nullopt;
    return number(key);
  }

  cv::Mat matrix(const std::string& key) const {
    cv::FileNode node = fs_[key];
    if (node.empty() || node.isNone()) throw InputError(path_, 0, "missing key '" + key + "'");
    cv::Mat m;
    try {
      node >> m;
    } catch (const cv::Exception& e) {
      throw InputError(path_, 0, "key '" + key + "' must be an opencv-matrix (" + e.msg + ")");
    }
    if (m.empty()) throw InputError(path_, 0, "key '" + key + "' must be an opencv-matrix");
    m.convertTo(m, CV_64F);
    return m;
  }

  const std::string& path() const { return path_; }

 private:
  std::string path_;
  cv::FileStorage fs_;
};

void require(bool ok, const std::string& source, const std::string& problem) {
  if (!ok) throw InputError(source.empty() ? "<settings>" : source, 0, problem);
}

}  // namespace

bool CameraSettings::has_distortion() const { return cv::countNonZero(dist != 0.0) > 0; }

Settings Settings::load(const std::string& path) {
  Reader r(path);
  Settings s;
  s.source = path;
  CameraSettings& c = s.camera;
  c.fx = r.number("Camera.fx");
  c.fy = r.number("Camera.fy");
  c.cx = r.number("Camera.cx");
  c.cy = r.number("Camera.cy");
  double k3 = r.optional_number("Camera.k3").value_or(0.0);
  c.dist = cv::Mat::zeros(1, r.has("Camera.k3") ? 5 : 4, CV_64F);
  c.dist.at<double>(0) = r.optional_number("Camera.k1").value_or(0.0);
  c.dist.at<double>(1) = r.optional_number("Camera.k2").value_or(0.0);
  c.dist.at<double>(2) = r.optional_number("Camera.p1").value_or(0.0);
  c.dist.at<double>(3) = r.optional_number("Camera.p2").value_or(0.0);
  if (c.dist.cols == 5) c.dist.at<double>(4) = k3;
  c.width = static_cast<int>(r.optional_number("Camera.width").value_or(0));
  c.height = static_cast<int>(r.optional_number("Camera.height").value_or(0));
  c.fps = r.optional_number("Camera.fps").value_or(30.0);
  c.rgb = r.optional_number("Camera.RGB").value_or(1.0) != 0.0;
  c.bf = r.optional_number("Camera.bf");
  c.th_depth = r.optional_number("ThDepth");
  c.depth_map_factor = r.optional_number("DepthMapFactor");

  ExtractorSettings& e = s.extractor;
  e.n_features = static_cast<int>(r.optional_number("ORBextractor.nFeatures").value_or(e.n_features));
  e.scale_factor = r.optional_number("ORBextractor.scaleFactor").value_or(e.scale_factor);
  e.n_levels = static_cast<int>(r.optional_number("ORBextractor.nLevels").value_or(e.n_levels));
  e.ini_th_fast = static_cast<int>(r.optional_number("ORBextractor.iniThFAST").value_or(e.ini_th_fast));
  e.min_th_fast = static_cast<int>(r.optional_number("ORBextractor.minThFAST").value_or(e.min_th_fast));

  if (r.has("LEFT.K") || r.has("RIGHT.K")) {
    StereoRectification& q = s.rectification;
    q.height = static_cast<int>(r.number("LEFT.height"));
    q.width = static_cast<int>(r.number("LEFT.width"));
    q.K_l = r.matrix("LEFT.K");
    q.D_l = r.matrix("LEFT.D");
    q.R_l = r.matrix("LEFT.R");
    q.P_l = r.matrix("LEFT.P");
    q.K_r = r.matrix("RIGHT.K");
    q.D_r = r.matrix("RIGHT.D");
    q.R_r = r.matrix("RIGHT.R");
    q.P_r = r.matrix("RIGHT.P");
    if (q.K_l.size() != cv::Size(3, 3) || q.K_r.size() != cv::Size(3, 3) ||
        q.R_l.size() != cv::Size(3, 3) || q.R_r.size() != cv::Size(3, 3) ||
        q.P_l.size() != cv::Size(4, 3) || q.P_r.size() != cv::Size(4, 3))
      throw InputError(path, 0, "LEFT./RIGHT. K and R must be 3x3 and P 3x4");
  }
  s.validate(Sensor::kMono);
  return s;
}

void Settings::validate(Sensor sensor) const {
  const CameraSettings& c = camera;
  require(c.fx > 0 && c.fy > 0, source, "Camera.fx and Camera.fy must be positive");
  require(c.width >= 0 && c.height >= 0, source, "Camera.width/height must not be negative");
  require(c.fps > 0, source, "Camera.fps must be positive");
  const ExtractorSettings& e = extractor;
  require(e.n_features > 0, source, "ORBextractor.nFeatures must be positive");
  require(e.scale_factor > 1.0, source, "ORBextractor.scaleFactor must be > 1");
  require(e.n_levels >= 1, source, "ORBextractor.nLevels must be >= 1");
  require(e.min_th_fast > 0 && e.ini_th_fast >= e.min_th_fast, source,
          "ORBextractor needs 0 < minThFAST <= iniThFAST");
  if (sensor == Sensor::kStereo || sensor == Sensor::kRGBD) {
    require(c.bf.has_value(), source, "missing key 'Camera.bf' (required for " + to_string(sensor) + ")");
    require(*c.bf > 0, source, "Camera.bf must be positive");
    require(c.th_depth.has_value(), source, "missing key 'ThDepth' (required for " + to_string(sensor) + ")");
    require(*c.th_depth > 0, source, "ThDepth must be positive");
  }
  if (sensor == Sensor::kRGBD) {
    require(c.depth_map_factor.has_value(), source, "missing key 'DepthMapFactor' (required for rgbd)");
    require(*c.depth_map_factor != 0.0, source, "DepthMapFactor must not be zero");
  }
}

namespace {

// OpenCV's writer refuses keys with dots ("Camera.fx"), so the ORB-SLAM2 layout
// is written by hand; the reader above is OpenCV's.
void write_matrix(std::ostream& out, const std::string& key, const cv::Mat& m) {
  out << key << ": !!opencv-matrix\n   rows: " << m.rows << "\n   cols: " << m.cols
      << "\n   dt: d\n   data: [";
  for (int i = 0; i < m.rows * m.cols; ++i) out << (i ? ", " : "") << m.at<double>(i / m.cols, i % m.cols);
  out << "]\n";
}

}  // namespace

void Settings::save(const std::string& path) const {
  std::ofstream out(path);
  if (!out) throw InputError(path, 0, "cannot write settings file");
  out << std::setprecision(17) << "%YAML:1.0\n";
  const CameraSettings& c = camera;
  out << "Camera.fx: " << c.fx << "\nCamera.fy: " << c.fy << "\nCamera.cx: " << c.cx << "\nCamera.cy: " << c.cy
      << "\n";
  const char* names[] = {"Camera.k1", "Camera.k2", "Camera.p1", "Camera.p2", "Camera.k3"};
  for (int i = 0; i < c.dist.cols && i < 5; ++i) out << names[i] << ": " << c.dist.at<double>(i) << "\n";
  if (c.width > 0) out << "Camera.width: " << c.width << "\nCamera.height: " << c.height << "\n";
  out << "Camera.fps: " << c.fps << "\nCamera.RGB: " << (c.rgb ? 1 : 0) << "\n";
  if (c.bf) out << "Camera.bf: " << *c.bf << "\n";
  if (c.th_depth) out << "ThDepth: " << *c.th_depth << "\n";
  if (c.depth_map_factor) out << "DepthMapFactor: " << *c.depth_map_factor << "\n";
  const ExtractorSettings& e = extractor;
  out << "ORBextractor.nFeatures: " << e.n_features << "\nORBextractor.scaleFactor: " << e.scale_factor
      << "\nORBextractor.nLevels: " << e.n_levels << "\nORBextractor.iniThFAST: " << e.ini_th_fast
      << "\nORBextractor.minThFAST: " << e.min_th_fast << "\n";
  if (rectification.enabled()) {
    const StereoRectification& q = rectification;
    for (const char* side : {"LEFT", "RIGHT"}) {
      const bool l = side[0] == 'L';
      const std::string p = side;
      out << p << ".height: " << q.height << "\n" << p << ".width: " << q.width << "\n";
      write_matrix(out, p + ".D", l ? q.D_l : q.D_r);
      write_matrix(out, p + ".K", l ? q.K_l : q.K_r);
      write_matrix(out, p + ".R", l ? q.R_l : q.R_r);
      write_matrix(out, p + ".P", l ? q.P_l : q.P_r);
    }
  }
  if (!out) throw InputError(path, 0, "write failed");
}

std::string Settings::summary() const {
  std::ostringstream o;
  const CameraSettings& c = camera;
  o << "settings: " << (source.empty() ? "<built in>" : source) << "\n"
    << "  camera: fx " << c.fx << " fy " << c.fy << " cx " << c.cx << " cy " << c.cy
    << " dist " << cv::format(c.dist, cv::Formatter::FMT_CSV) << "\n"
    << "  size " << c.width << "x" << c.height << " fps " << c.fps << " RGB " << c.rgb;
  if (c.bf) o << " bf " << *c.bf;
  if (c.th_depth) o << " ThDepth " << *c.th_depth;
  if (c.depth_map_factor) o << " DepthMapFactor " << *c.depth_map_factor;
  o << "\n  ORB: " << extractor.n_features << " features, scale " << extractor.scale_factor << ", "
    << extractor.n_levels << " levels, FAST " << extractor.ini_th_fast << "/" << extractor.min_th_fast
    << "\n  stereo rectification: " << (rectification.enabled() ? "yes" : "no");
  return o.str();
}

}  // namespace dynaorb
