#pragma once
// Which points of an image lie near a line: the epipolar band query of the exhaustive
// triangulation search (Matcher::search_for_triangulation without a vocabulary). Each point k
// has its own squared distance limit (3.84 sigma^2 of its octave there) and is near line
// l = (a, b, c) when !(num * num / norm2 >= limit2[k]), num = a x + b y + c, norm2 = a^2 + b^2:
// the test written in the search, so the same points pass as if every point were tested.
//
// The points are bucketed twice, into strips along x (each sorted by y) and strips along y
// (each sorted by x). A query takes the bucketing across which the line runs at the shallower
// angle, bounds the band in each strip from the line at the strip's two ends and the largest
// limit (plus a pixel of slack), binary-searches that range and applies the exact test to what
// lies inside. A line that is not finite (or has a = b = 0) falls back to testing every point.
#include <Eigen/Core>
#include <vector>

namespace dynaorb::match {

class EpipolarBand {
 public:
  struct Point {
    double x = 0, y = 0;
    double limit2 = 0;  // squared distance limit
    int id = 0;
  };

  explicit EpipolarBand(std::vector<Point> points, int strips = 16);

  // Ids of the points near `line`, ascending by their index in the constructor's vector.
  // Uses a scratch buffer of the object: one query at a time per object.
  void near(const Eigen::Vector3d& line, std::vector<int>* ids) const;

 private:
  struct Entry {
    double along;  // the coordinate a strip is sorted by
    int index;     // into points_
  };
  // Strips across one axis: strip s holds the points with coordinate in [lo + s * width,
  // lo + (s + 1) * width) (the last one up to and including the largest).
  struct Strips {
    double lo = 0, width = 1;
    std::vector<std::vector<Entry>> strip;
  };
  Strips bucket(bool across_x, int n) const;  // the finite points of points_
  bool passes(const Eigen::Vector3d& line, double norm2, int index) const;

  std::vector<Point> points_;
  double max_distance_ = 0;  // sqrt of the largest limit2
  Strips by_x_, by_y_;       // strips across x (sorted by y) and across y (sorted by x)
  std::vector<int> unbucketed_;  // points with a non-finite coordinate or limit: always tested
  mutable std::vector<int> hits_;  // near()'s scratch
};

}  // namespace dynaorb::match
