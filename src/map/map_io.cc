#include "dynaorb/map/map_io.h"

#include <cmath>
#include <cstring>
#include <fstream>
#include <iterator>
#include <map>
#include <sstream>
#include <type_traits>
#include <unordered_map>
#include <utility>
#include <vector>

#include "dynaorb/io/errors.h"
#include "dynaorb/map/bag_of_words.h"
#include "dynaorb/place/keyframe_database.h"
#include "dynaorb/vocab/vocabulary.h"
#include "map_file_format.h"

namespace dynaorb::map {

using namespace file;  // NOLINT: the format helpers of map_file_format.h

// Restores what only Map, KeyFrame and MapPoint may set (friend of all three).
class MapIo {
 public:
  static void write(Writer& w, const Map& map, const LoopEdges& loop_edges) {
    w.put<std::int64_t>(map.next_keyframe_id_);
    w.put<std::int64_t>(map.next_point_id_);
    w.put<std::uint64_t>(map.keyframes_.size());
    for (const auto& [id, kf] : map.keyframes_) {
      w.put<std::int64_t>(kf->id);
      w.put<std::int64_t>(kf->frame_id);
      w.put<double>(kf->stamp);
      w.put_pose(kf->T_cw_);
      w.put<std::int64_t>(kf->parent_ && map.keyframes_.count(kf->parent_->id) ? kf->parent_->id : -1);
      w.put<std::uint8_t>(kf->not_erase ? 1 : 0);
      const Features& f = kf->f();
      w.put_keys(f.keys);
      w.put_keys(f.keys_un);
      const cv::Mat d = f.descriptors.isContinuous() ? f.descriptors : f.descriptors.clone();
      w.put<std::uint64_t>(d.empty() ? 0 : static_cast<std::uint64_t>(d.rows));
      if (!d.empty()) w.put_bytes(d.data, static_cast<std::size_t>(d.rows) * 32);
      w.put<std::uint64_t>(f.u_right.size());
      w.put_bytes(f.u_right.data(), f.u_right.size() * sizeof(float));
      w.put<std::uint64_t>(f.depth.size());
      w.put_bytes(f.depth.data(), f.depth.size() * sizeof(float));
    }
    w.put<std::uint64_t>(map.points_.size());
    for (const auto& [id, p] : map.points_) {
      std::vector<MapPoint::Observation> obs;
      for (const MapPoint::Observation& o : p->observations_)
        if (map.keyframes_.count(o.keyframe->id)) obs.push_back(o);
      long ref = p->reference_ && map.keyframes_.count(p->reference_->id) ? p->reference_->id : -1;
      if (ref < 0 && !obs.empty()) ref = obs.front().keyframe->id;
      w.put<std::int64_t>(p->id);
      w.put<std::int64_t>(p->first_keyframe_id);
      for (int k = 0; k < 3; ++k) w.put<double>(p->position_(k));
      w.put<std::int64_t>(ref);
      w.put_bytes(p->descriptor_.data(), 32);
      for (int k = 0; k < 3; ++k) w.put<double>(p->normal_(k));
      w.put<double>(p->min_distance_);
      w.put<double>(p->max_distance_);
      w.put<std::int32_t>(p->visible_);
      w.put<std::int32_t>(p->found_);
      w.put<std::uint64_t>(obs.size());
      for (const MapPoint::Observation& o : obs) {
        w.put<std::int64_t>(o.keyframe->id);
        w.put<std::int32_t>(o.index);
      }
    }
    // Version 2: the loop edges, each pair once (a < b), both ends in the map.
    std::vector<std::pair<long, long>> edges;
    for (const auto& [a, partners] : loop_edges)
      for (long b : partners)
        if (a < b && map.keyframes_.count(a) && map.keyframes_.count(b)) edges.emplace_back(a, b);
    w.put<std::uint64_t>(edges.size());
    for (const auto& [a, b] : edges) {
      w.put<std::int64_t>(a);
      w.put<std::int64_t>(b);
    }
  }

  // Parses everything into new objects; the map is replaced only at the end.
  static void read(Reader& r, std::uint32_t version, Map& map, const std::shared_ptr<const Calibration>& calib,
                   const LoadOptions& o) {
    const long next_kf = r.get<std::int64_t>("the id counters");
    const long next_point = r.get<std::int64_t>("the id counters");
    std::map<long, std::shared_ptr<KeyFrame>> kfs;
    std::map<long, long> parents;
    const std::size_t n_kf = r.count(8 * 3 + 96 + 9, "the keyframes");
    for (std::size_t k = 0; k < n_kf; ++k) {
      const long id = r.get<std::int64_t>("a keyframe");
      const long frame_id = r.get<std::int64_t>("a keyframe");
      const double stamp = r.get<double>("a keyframe");
      const Eigen::Isometry3d T_cw = r.pose("a keyframe pose");
      const long parent = r.get<std::int64_t>("a keyframe");
      const bool not_erase = r.get<std::uint8_t>("a keyframe") != 0;
      auto f = std::make_shared<Features>();
      f->calib = calib;
      f->keys = r.keys(calib->scale.n_levels, "keypoints");
      f->keys_un = r.keys(calib->scale.n_levels, "undistorted keypoints");
      const std::size_t n = f->keys_un.size();
      const std::size_t n_desc = r.count(32, "descriptors");
      if (f->keys.size() != n || n_desc != n)
        r.fail("corrupt map file: keyframe " + std::to_string(id) + " has " + std::to_string(f->keys.size()) +
               " keypoints, " + std::to_string(n) + " undistorted, " + std::to_string(n_desc) + " descriptors");
      f->descriptors = cv::Mat(static_cast<int>(n), 32, CV_8U);
      if (n > 0) r.get_bytes(f->descriptors.data, n * 32, "descriptors");
      f->u_right.resize(r.count(4, "u_right"));
      r.get_bytes(f->u_right.data(), f->u_right.size() * 4, "u_right");
      f->depth.resize(r.count(4, "depths"));
      r.get_bytes(f->depth.data(), f->depth.size() * 4, "depths");
      if (f->u_right.size() != n || f->depth.size() != n)
        r.fail("corrupt map file: keyframe " + std::to_string(id) + " has " + std::to_string(n) + " keypoints but " +
               std::to_string(f->u_right.size()) + " u_right and " + std::to_string(f->depth.size()) + " depths");
      f->build_grid();
      if (id < 0 || id >= next_kf || kfs.count(id))
        r.fail("corrupt map file: keyframe id " + std::to_string(id) + " repeated or out of range");
      auto kf = std::make_shared<KeyFrame>(id, frame_id, stamp, std::move(f), T_cw);
      kf->not_erase = not_erase;
      kf->first_connection_ = false;
      kfs[id] = kf;
      parents[id] = parent;
    }
    for (const auto& [id, parent] : parents)
      if (parent >= 0 && (!kfs.count(parent) || parent == id))
        r.fail("corrupt map file: keyframe " + std::to_string(id) + " has an unknown parent " + std::to_string(parent));

    std::map<long, std::shared_ptr<MapPoint>> points;
    const std::size_t n_points = r.count(8 * 2 + 24 + 8 + 32 + 24 + 16 + 8 + 8, "the map points");
    for (std::size_t k = 0; k < n_points; ++k) {
      const long id = r.get<std::int64_t>("a map point");
      const long first_kf = r.get<std::int64_t>("a map point");
      Eigen::Vector3d pos, normal;
      for (int i = 0; i < 3; ++i) pos(i) = r.finite("a map point position");
      const long ref = r.get<std::int64_t>("a map point");
      MapPoint::Descriptor desc;
      r.get_bytes(desc.data(), 32, "a map point descriptor");
      for (int i = 0; i < 3; ++i) normal(i) = r.finite("a map point normal");
      const double min_d = r.finite("a map point distance range");
      const double max_d = r.finite("a map point distance range");
      const int visible = r.get<std::int32_t>("a map point");
      const int found = r.get<std::int32_t>("a map point");
      if (id < 0 || id >= next_point || points.count(id))
        r.fail("corrupt map file: map point id " + std::to_string(id) + " repeated or out of range");
      auto it = kfs.find(ref);
      if (it == kfs.end())
        r.fail("corrupt map file: map point " + std::to_string(id) + " has an unknown reference keyframe");
      auto p = std::make_shared<MapPoint>(id, pos, it->second.get(), first_kf);
      std::memcpy(p->descriptor_.data(), desc.data(), 32);
      p->normal_ = normal;
      p->min_distance_ = min_d;
      p->max_distance_ = max_d;
      p->visible_ = visible;
      p->found_ = found;
      const std::size_t n_obs = r.count(12, "observations");
      for (std::size_t j = 0; j < n_obs; ++j) {
        const long kf_id = r.get<std::int64_t>("an observation");
        const int index = r.get<std::int32_t>("an observation");
        auto kit = kfs.find(kf_id);
        if (kit == kfs.end() || index < 0 || index >= kit->second->f().size() || kit->second->point(index) ||
            p->index_in(kit->second.get()) >= 0)
          r.fail("corrupt map file: map point " + std::to_string(id) + " has an impossible observation (keyframe " +
                 std::to_string(kf_id) + ", keypoint " + std::to_string(index) + ")");
        kit->second->set_point(index, p);
        p->add_observation(kit->second.get(), index);
      }
      if (p->index_in(it->second.get()) < 0)
        r.fail("corrupt map file: map point " + std::to_string(id) + " is not observed by its reference keyframe");
      points[id] = p;
    }
    LoopEdges loop_edges;
    if (version >= 2) {
      const std::size_t n_edges = r.count(16, "the loop edges");
      for (std::size_t k = 0; k < n_edges; ++k) {
        const long a = r.get<std::int64_t>("a loop edge"), b = r.get<std::int64_t>("a loop edge");
        if (a == b || !kfs.count(a) || !kfs.count(b))
          r.fail("corrupt map file: loop edge " + std::to_string(a) + "-" + std::to_string(b) +
                 " does not join two keyframes of the file");
        loop_edges[a].insert(b);
        loop_edges[b].insert(a);
      }
    }
    if (r.remaining() != 0) r.fail("corrupt map file: " + std::to_string(r.remaining()) + " bytes left after the map");

    // Checked: replace the map.
    map.clear();
    for (const auto& [id, kf] : kfs) map.add_keyframe(kf);
    for (const auto& [id, p] : points) map.add_point(p);
    map.next_keyframe_id_ = next_kf;
    map.next_point_id_ = next_point;
    for (const auto& [id, kf] : kfs) kf->update_connections(o.covisibility_min_weight);
    for (const auto& [id, kf] : kfs) {
      const long parent = parents[id];
      kf->set_parent(parent >= 0 ? kfs[parent].get() : nullptr);
    }
    if (o.vocabulary) {
      for (const auto& [id, kf] : kfs) {
        kf->set_bow(BagOfWords::compute(*o.vocabulary, kf->f()));
        if (o.database) o.database->add(*kf);
      }
    }
    if (o.loop_edges) *o.loop_edges = std::move(loop_edges);
  }
};

void save_map(const std::string& path, const Map& map, const Calibration& calib, Sensor sensor,
              const LoopEdges& loop_edges) {
  Writer w;
  put_info(w, calib, sensor);
  MapIo::write(w, map, loop_edges);
  const std::string& payload = w.buffer();
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) throw InputError(path, 0, "cannot write the map file");
  const std::uint32_t version = kMapFormatVersion;
  const std::uint64_t n = payload.size(), checksum = fnv1a(payload.data(), payload.size());
  out.write(kMapMagic, 8);
  out.write(reinterpret_cast<const char*>(&version), 4);
  out.write(reinterpret_cast<const char*>(&n), 8);
  out.write(reinterpret_cast<const char*>(&checksum), 8);
  out.write(payload.data(), static_cast<std::streamsize>(payload.size()));
  out.close();
  if (!out) throw InputError(path, 0, "cannot write the map file (disk full?)");
}

namespace {
MapFileInfo info_of(const std::string& path, const std::string& data, std::unique_ptr<Reader>& reader) {
  MapFileInfo info;
  reader = std::make_unique<Reader>(open_payload(path, data, info));
  MapFileInfo c = get_info(*reader);
  c.version = info.version;
  c.file_bytes = info.file_bytes;
  return c;
}
}  // namespace

MapFileInfo read_map_info(const std::string& path) {
  const std::string data = read_file(path);
  std::unique_ptr<Reader> r;
  return info_of(path, data, r);
}

std::string calibration_mismatch(const MapFileInfo& info, const Calibration& c, Sensor sensor) {
  if (info.sensor != sensor)
    return "the map was made with a " + to_string(info.sensor) + " camera, this system is " + to_string(sensor);
  if (info.width != c.width || info.height != c.height)
    return "the map was made with " + std::to_string(info.width) + "x" + std::to_string(info.height) +
           " images, this system's are " + std::to_string(c.width) + "x" + std::to_string(c.height);
  const std::pair<const char*, std::pair<double, double>> values[] = {
      {"fx", {info.fx, c.fx}}, {"fy", {info.fy, c.fy}}, {"cx", {info.cx, c.cx}}, {"cy", {info.cy, c.cy}},
      {"bf", {info.bf, c.bf}}, {"th_depth", {info.th_depth, c.th_depth}},
      {"ORB scale factor", {info.scale_factor, c.scale.scale_factor}}};
  for (const auto& [name, v] : values)
    if (!close(v.first, v.second))
      return std::string("the map was made with ") + name + " = " + num(v.first) + ", this system has " +
             num(v.second) + " (another camera calibration)";
  if (info.n_levels != c.scale.n_levels)
    return "the map was made with " + std::to_string(info.n_levels) + " ORB pyramid levels, this system has " +
           std::to_string(c.scale.n_levels);
  cv::Mat d;
  if (!c.dist.empty()) c.dist.reshape(1, 1).convertTo(d, CV_64F);
  bool same = d.total() == info.dist.size();
  for (std::size_t i = 0; same && i < info.dist.size(); ++i)
    same = close(info.dist[i], d.at<double>(0, static_cast<int>(i)));
  if (!same) return "the map was made with another lens distortion than this system's";
  return {};
}

MapFileInfo load_map(const std::string& path, Map& map, const std::shared_ptr<const Calibration>& calib,
                     Sensor sensor, const LoadOptions& options) {
  const std::string data = read_file(path);
  std::unique_ptr<Reader> r;
  MapFileInfo info = info_of(path, data, r);
  const std::string why = calibration_mismatch(info, *calib, sensor);
  if (!why.empty()) throw InputError(path, 0, "map refused: " + why);
  MapIo::read(*r, info.version, map, calib, options);
  info.keyframes = static_cast<long>(map.keyframe_count());
  info.points = static_cast<long>(map.point_count());
  return info;
}

}  // namespace dynaorb::map
