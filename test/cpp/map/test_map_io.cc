// Map files (map/map_io.h): a round trip keeps every keyframe, point,
// observation and the covisibility graph exactly; bad files are refused with
// an InputError naming the file, and the map is left as it was.
#include <gtest/gtest.h>

#include <chrono>
#include <cstring>
#include <fstream>
#include <iterator>

#include "../place/place_test_util.h"
#include "dynaorb/io/errors.h"
#include "dynaorb/map/map_io.h"
#include "dynaorb/system.h"

namespace dynaorb::test {
namespace {

using map::KeyFrame;
using map::MapPoint;

std::string read_bytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

void write_bytes(const fs::path& p, const std::string& s) { std::ofstream(p, std::ios::binary) << s; }

// An edited map file with its header's payload length and FNV-1a checksum
// made to match again (the 28-byte header: magic, version, length, checksum).
std::string resealed(std::string f) {
  const std::uint64_t payload = f.size() - 28;
  std::memcpy(&f[12], &payload, 8);
  std::uint64_t h = 1469598103934665603ull;
  for (size_t i = 28; i < f.size(); ++i) h = (h ^ static_cast<unsigned char>(f[i])) * 1099511628211ull;
  std::memcpy(&f[20], &h, 8);
  return f;
}

// KITTI 06 keyframes 0..7 at their ground-truth poses; each keyframe's points
// also observed by the next keyframe at the same keypoint (a graph, not
// geometry), some points erased or fused, one keyframe culled.
struct TestMap {
  map::Map map;
  std::shared_ptr<const map::Calibration> calib;
  TestMap() {
    std::lock_guard<std::mutex> lk(map.mutex());
    std::vector<std::shared_ptr<KeyFrame>> kfs;
    for (int i = 0; i < 8; ++i) kfs.push_back(make_keyframe(map, i));
    calib = kfs[0]->features->calib;
    for (int i = 0; i + 1 < 8; ++i) {
      int shared = 0;
      for (int k = 0; k < kfs[i]->f().size() && shared < 40 + 10 * i; ++k) {
        const auto p = kfs[i]->point(k);
        if (!p || kfs[i + 1]->point(k) || k >= kfs[i + 1]->f().size()) continue;
        map.add_observation(*kfs[i + 1], k, p);
        ++shared;
      }
    }
    for (const auto& kf : kfs) kf->update_connections();
    const auto pts = map.points();
    map.erase_point(pts[3]);
    map.replace_point(pts[10], pts[11]);
    pts[12]->increase_visible(7);
    pts[12]->increase_found(3);
    kfs[2]->not_erase = true;
    map.erase_keyframe(kfs[5]);  // children re-linked, its observations gone
  }
};

void expect_same_maps(const map::Map& a, const map::Map& b) {
  const auto ka = a.keyframes(), kb = b.keyframes();
  ASSERT_EQ(ka.size(), kb.size());
  for (size_t i = 0; i < ka.size(); ++i) {
    const KeyFrame& x = *ka[i];
    const KeyFrame& y = *kb[i];
    ASSERT_EQ(x.id, y.id);
    EXPECT_EQ(x.frame_id, y.frame_id);
    EXPECT_EQ(x.stamp, y.stamp);
    EXPECT_TRUE(x.T_cw().matrix() == y.T_cw().matrix()) << "keyframe " << x.id;
    EXPECT_EQ(x.not_erase, y.not_erase);
    EXPECT_EQ(x.parent() ? x.parent()->id : -1, y.parent() ? y.parent()->id : -1) << "keyframe " << x.id;
    ASSERT_EQ(x.f().size(), y.f().size());
    for (int k = 0; k < x.f().size(); ++k) {
      EXPECT_EQ(x.f().keys[k].pt, y.f().keys[k].pt);
      EXPECT_EQ(x.f().keys_un[k].pt, y.f().keys_un[k].pt);
      EXPECT_EQ(x.f().keys_un[k].octave, y.f().keys_un[k].octave);
      EXPECT_EQ(x.f().keys_un[k].angle, y.f().keys_un[k].angle);
      EXPECT_EQ(x.f().u_right[k], y.f().u_right[k]);
      EXPECT_EQ(x.f().depth[k], y.f().depth[k]);
      EXPECT_EQ((x.point(k) ? x.point(k)->id : -1), (y.point(k) ? y.point(k)->id : -1));
    }
    EXPECT_EQ(cv::norm(x.f().descriptors, y.f().descriptors, cv::NORM_HAMMING), 0);
    // Covisibility: same neighbours in the same order with the same weights.
    const auto cx = x.covisibles(), cy = y.covisibles();
    ASSERT_EQ(cx.size(), cy.size()) << "keyframe " << x.id;
    for (size_t j = 0; j < cx.size(); ++j) {
      EXPECT_EQ(cx[j]->id, cy[j]->id);
      EXPECT_EQ(x.weight(cx[j]), y.weight(cy[j]));
    }
    // Grid rebuilt: the same radius search.
    EXPECT_EQ(x.f().in_area(600, 180, 40), y.f().in_area(600, 180, 40));
  }
  const auto pa = a.points(), pb = b.points();
  ASSERT_EQ(pa.size(), pb.size());
  for (size_t i = 0; i < pa.size(); ++i) {
    const MapPoint& x = *pa[i];
    const MapPoint& y = *pb[i];
    ASSERT_EQ(x.id, y.id);
    EXPECT_EQ(x.first_keyframe_id, y.first_keyframe_id);
    EXPECT_TRUE(x.position() == y.position());
    EXPECT_EQ(x.reference()->id, y.reference()->id);
    EXPECT_EQ(x.descriptor(), y.descriptor());
    EXPECT_TRUE(x.normal() == y.normal());
    EXPECT_EQ(x.min_distance(), y.min_distance());
    EXPECT_EQ(x.max_distance(), y.max_distance());
    EXPECT_EQ(x.visible(), y.visible());
    EXPECT_EQ(x.found(), y.found());
    EXPECT_EQ(x.observation_count(), y.observation_count());
    ASSERT_EQ(x.observations().size(), y.observations().size());
    for (size_t j = 0; j < x.observations().size(); ++j) {
      EXPECT_EQ(x.observations()[j].keyframe->id, y.observations()[j].keyframe->id);
      EXPECT_EQ(x.observations()[j].index, y.observations()[j].index);
    }
  }
}

TEST(MapIo, RoundTripKeepsTheMapExactly) {
  REQUIRE_PLACE_DATA();
  TestMap t;
  ScratchDir dir;
  const fs::path file = dir.path() / "a.map";
  std::lock_guard<std::mutex> lk(t.map.mutex());
  map::save_map(file.string(), t.map, *t.calib, Sensor::kStereo);
  // Loading rebuilds covisibility with UpdateConnections on every keyframe,
  // by id: the original's graph after the same rebuild.
  for (const auto& kf : t.map.keyframes()) kf->update_connections();

  const map::MapFileInfo info = map::read_map_info(file.string());
  EXPECT_EQ(info.version, map::kMapFormatVersion);
  EXPECT_EQ(info.sensor, Sensor::kStereo);
  EXPECT_EQ(info.width, t.calib->width);
  EXPECT_EQ(info.fx, t.calib->fx);
  EXPECT_EQ(info.file_bytes, fs::file_size(file));

  map::Map loaded;
  place::KeyFrameDatabase db(loaded, place_data().vocabulary);
  std::lock_guard<std::mutex> lk2(loaded.mutex());
  map::LoadOptions o;
  o.vocabulary = place_data().vocabulary.get();
  o.database = &db;
  const map::MapFileInfo got = map::load_map(file.string(), loaded, t.calib, Sensor::kStereo, o);
  EXPECT_EQ(got.keyframes, 7);
  EXPECT_EQ(got.points, static_cast<long>(t.map.point_count()));
  expect_same_maps(t.map, loaded);
  EXPECT_EQ(db.size(), 7u);
  for (const auto& kf : loaded.keyframes()) ASSERT_TRUE(kf->bow());
  // Saving the loaded map gives the same file.
  const fs::path again = dir.path() / "b.map";
  map::save_map(again.string(), loaded, *t.calib, Sensor::kStereo);
  EXPECT_TRUE(read_bytes(file) == read_bytes(again));
  // The id counters continue where the saved map's stopped.
  EXPECT_EQ(loaded.new_keyframe_id(), t.map.new_keyframe_id());
  EXPECT_EQ(loaded.new_point_id(), t.map.new_point_id());
  // A frame finds its keyframe through the rebuilt database.
  const auto cands = db.relocalization_candidates(make_frame(3).bow->words);
  ASSERT_FALSE(cands.empty());
}

TEST(MapIo, BadFilesAreRefusedWithTheFileNamed) {
  REQUIRE_PLACE_DATA();
  TestMap t;
  ScratchDir dir;
  const fs::path good = dir.path() / "good.map";
  std::unique_lock<std::mutex> lk(t.map.mutex());
  map::save_map(good.string(), t.map, *t.calib, Sensor::kStereo);
  lk.unlock();
  const std::string bytes = read_bytes(good);

  map::Map target;  // holds a map that a refused file must leave alone
  std::lock_guard<std::mutex> lk2(target.mutex());
  map::load_map(good.string(), target, t.calib, Sensor::kStereo);
  const size_t kfs = target.keyframe_count(), pts = target.point_count();

  auto expect_refused = [&](const std::string& name, const std::string& content, const std::string& why) {
    const fs::path p = dir.path() / name;
    if (!content.empty() || name != "missing.map") write_bytes(p, content);
    try {
      map::load_map(p.string(), target, t.calib, Sensor::kStereo);
      ADD_FAILURE() << name << " was loaded";
    } catch (const InputError& e) {
      const std::string msg = e.what();
      EXPECT_NE(msg.find(p.string()), std::string::npos) << msg;
      EXPECT_NE(msg.find(why), std::string::npos) << msg;
      EXPECT_EQ(e.file(), p.string());
    }
    EXPECT_EQ(target.keyframe_count(), kfs) << name;
    EXPECT_EQ(target.point_count(), pts) << name;
  };
  expect_refused("missing.map", "", "cannot open");
  expect_refused("empty.map", "", "not a dynaorb map file");
  std::string s = bytes;
  s[0] = 'X';
  expect_refused("magic.map", s, "not a dynaorb map file");
  expect_refused("text.map", "hello, this is not a map at all, not even close", "not a dynaorb map file");
  s = bytes;
  s[8] = 3;
  expect_refused("version.map", s, "format version 3");
  s[8] = 0;
  expect_refused("version0.map", s, "format version 0");
  expect_refused("header.map", bytes.substr(0, 15), "truncated");
  expect_refused("truncated.map", bytes.substr(0, bytes.size() / 2), "truncated");
  expect_refused("one_short.map", bytes.substr(0, bytes.size() - 1), "truncated");
  expect_refused("trailing.map", bytes + "xx", "corrupt");
  s = bytes;
  s[bytes.size() / 3] ^= 0x40;
  expect_refused("flipped.map", s, "checksum");
  // Payloads that pass the checksum but contradict themselves (a writer's bug).
  std::uint64_t n_dist;
  std::memcpy(&n_dist, bytes.data() + 28 + 4 + 8 + 48, 8);
  const size_t kf_count_at = 28 + 4 + 8 + 48 + 8 + 8 * n_dist + 4 + 8 + 16;
  s = bytes;
  const std::uint64_t huge = 1ull << 60;
  std::memcpy(&s[kf_count_at], &huge, 8);
  expect_refused("count.map", resealed(s), "exceeds the file");
  s = bytes;
  std::int64_t first_id = 999999;  // the first keyframe's id beyond the id counter
  std::memcpy(&s[kf_count_at + 8], &first_id, 8);
  expect_refused("kf_id.map", resealed(s), "keyframe id");
  s = bytes;
  s[kf_count_at + 8 + 8 + 8 + 8 + 96 + 8 + 1 + 8 + 20] = 77;  // first keypoint's octave
  expect_refused("octave.map", resealed(s), "pyramid level");

  // Another calibration or sensor: refused, naming what differs.
  auto other = std::make_shared<map::Calibration>(*t.calib);
  other->fx += 1.0;
  try {
    map::load_map(good.string(), target, other, Sensor::kStereo);
    ADD_FAILURE() << "another calibration was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("fx"), std::string::npos) << e.what();
  }
  EXPECT_THROW(map::load_map(good.string(), target, t.calib, Sensor::kRGBD), InputError);
  EXPECT_EQ(target.keyframe_count(), kfs);
}

// The loop closer's loop edges (format version 2) survive a save and a load;
// a version-1 file (no edge block) still loads, with none; an edge naming a
// keyframe the file does not hold is refused.
TEST(MapIo, LoopEdgesAreKeptAndVersionOneFilesStillLoad) {
  REQUIRE_PLACE_DATA();
  TestMap t;
  ScratchDir dir;
  std::lock_guard<std::mutex> lk(t.map.mutex());
  const auto kfs = t.map.keyframes();
  ASSERT_GE(kfs.size(), 3u);
  const long a = kfs.front()->id, b = kfs.back()->id, c = kfs[1]->id;
  const map::LoopEdges edges{{a, {b}}, {b, {a}}, {c, {999}}};  // 999: not in the map, left out
  const fs::path file = dir.path() / "loop.map";
  map::save_map(file.string(), t.map, *t.calib, Sensor::kStereo, edges);
  auto load = [&](const fs::path& p, map::Map& into) {
    std::lock_guard<std::mutex> l(into.mutex());
    map::LoopEdges got{{12345, {1}}};  // replaced by the file's
    map::LoadOptions o;
    o.loop_edges = &got;
    map::load_map(p.string(), into, t.calib, Sensor::kStereo, o);
    return got;
  };
  map::Map loaded;
  EXPECT_EQ(load(file, loaded), (map::LoopEdges{{a, {b}}, {b, {a}}}));
  EXPECT_EQ(loaded.keyframe_count(), t.map.keyframe_count());

  // Version 1: the same file without the edge block (count and one pair).
  std::string v1 = read_bytes(file);
  v1.resize(v1.size() - 8 - 16);
  const std::uint32_t one = 1;
  std::memcpy(&v1[8], &one, 4);
  const fs::path old_file = dir.path() / "v1.map";
  write_bytes(old_file, resealed(v1));
  EXPECT_EQ(map::read_map_info(old_file.string()).version, 1u);
  map::Map from_v1;
  EXPECT_TRUE(load(old_file, from_v1).empty());
  EXPECT_EQ(from_v1.keyframe_count(), t.map.keyframe_count());
  EXPECT_EQ(from_v1.point_count(), t.map.point_count());

  // An edge to a keyframe the file does not hold.
  std::string bad = read_bytes(file);
  const std::int64_t missing = 999999;
  std::memcpy(&bad[bad.size() - 8], &missing, 8);
  const fs::path bad_file = dir.path() / "bad_edge.map";
  write_bytes(bad_file, resealed(bad));
  map::Map untouched;
  try {
    load(bad_file, untouched);
    ADD_FAILURE() << "an edge to keyframe 999999 was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("loop edge"), std::string::npos) << e.what();
  }
  EXPECT_EQ(untouched.keyframe_count(), 0u);
}

// Through the System: KITTI 06 mapped, saved, loaded by another System (the
// same file again on saving), tracked in localisation only.
TEST(MapIo, SystemSavesLoadsAndLocalises) {
  REQUIRE_PLACE_DATA();
  const fs::path kitti = shared_data() / "kitti/sequences/06";
  auto provider = open_dataset("kitti", kitti.string());
  const Settings settings = provider->default_settings();
  SystemOptions o;
  o.synchronous_mapping = true;
  o.vocabulary = place_data().vocabulary;
  ScratchDir dir;
  const std::string file = (dir.path() / "kitti06.map").string();
  MapSummary made;
  {
    System s(settings, Sensor::kStereo, o);
    EXPECT_THROW(s.save_map(file), InputError);  // no map yet
    for (int i = 0; i < 20; ++i) {
      const dynaorb::Frame f = provider->load(i);
      s.track_stereo(f.image, f.right, f.stamp);
    }
    made = s.map_summary();
    ASSERT_GT(made.keyframes, 3);
    s.save_map(file);
  }
  System s(settings, Sensor::kStereo, o);
  s.load_map(file);
  EXPECT_EQ(s.map_summary().keyframes, made.keyframes);
  EXPECT_EQ(s.map_summary().points, made.points);
  const std::string again = (dir.path() / "again.map").string();
  s.save_map(again);
  EXPECT_TRUE(read_bytes(file) == read_bytes(again));

  s.set_localization_mode(true);
  EXPECT_TRUE(s.localization_mode());
  for (int i = 0; i < 20; ++i) {
    const dynaorb::Frame f = provider->load(i);
    const TrackResult r = s.track_stereo(f.image, f.right, f.stamp);
    EXPECT_EQ(r.state, TrackingState::kOk) << "frame " << i << " " << r.method;
    EXPECT_FALSE(r.new_keyframe);
    if (i == 0) {
      EXPECT_EQ(r.method, "relocalization");
    }
  }
  EXPECT_EQ(s.map_summary().keyframes, made.keyframes);
  EXPECT_EQ(s.map_summary().points, made.points);

  s.reset();
  EXPECT_EQ(s.map_summary().keyframes, 0);

  // Without a vocabulary a loaded map could not be relocalised in: refused.
  System none(settings, Sensor::kStereo, SystemOptions{});
  try {
    none.load_map(file);
    ADD_FAILURE() << "loaded without a vocabulary";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("vocabulary"), std::string::npos) << e.what();
  }
  // Another sensor: refused, the system still usable.
  Settings mono_settings = settings;
  System mono(mono_settings, Sensor::kMono, o);
  EXPECT_THROW(mono.load_map(file), InputError);
}

}  // namespace
}  // namespace dynaorb::test
