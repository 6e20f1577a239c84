// Vocabulary on real ORB descriptors (KITTI 06, EuRoC MH_05 and V1_01):
// training bounds and IDF, k-means on synthetic clusters, place recognition,
// the direct index, binary and ORBvoc.txt round trips, a hand-written
// ORBvoc.txt, and file errors.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <opencv2/features2d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include "../test_util.h"
#include "dynaorb/map/bag_of_words.h"
#include "dynaorb/vocab/vocabulary.h"

namespace dynaorb {
namespace {

using test::ScratchDir;
using test::shared_data;
using vocab::BowVector;
using vocab::FeatureVector;
using vocab::NodeId;
using vocab::Vocabulary;
using vocab::WordId;

constexpr int kK = 10, kL = 4;

std::vector<std::string> sorted_images(const std::string& rel) {
  std::vector<std::string> files;
  const auto dir = shared_data() / rel;
  if (!test::fs::is_directory(dir)) return files;
  for (const auto& e : test::fs::directory_iterator(dir))
    if (e.path().extension() == ".png") files.push_back(e.path().string());
  std::sort(files.begin(), files.end());
  return files;
}

cv::Mat orb_descriptors(const std::string& file) {
  static cv::Ptr<cv::ORB> orb = cv::ORB::create(1000);
  const cv::Mat img = cv::imread(file, cv::IMREAD_GRAYSCALE);
  std::vector<cv::KeyPoint> kps;
  cv::Mat d;
  if (!img.empty()) orb->detectAndCompute(img, cv::noArray(), kps, d);
  return d;
}

// Training: frames 0, 5, .., 45 of KITTI 06 (10 Hz) and 0, 25, .., 225 of
// MH_05 (20 Hz); V1_01 is unseen. Database frames f (query: f + 1) are never
// training frames.
struct Data {
  bool ok = false;
  std::vector<std::string> files[3];
  std::vector<int> database[3] = {{2, 12, 22, 32, 42}, {7, 57, 107, 157, 207}, {2, 32, 62, 92}};
  std::vector<cv::Mat> train;
  Vocabulary voc;
  double train_s = 0.0;
};

const Data& data() {
  static const Data d = [] {
    Data d;
    d.files[0] = sorted_images("kitti/sequences/06/image_0");
    d.files[1] = sorted_images("euroc/MH_05_difficult_head/mav0/cam0/data");
    d.files[2] = sorted_images("euroc/V1_01_easy_micro/mav0/cam0/data");
    if (d.files[0].size() < 51 || d.files[1].size() < 250 || d.files[2].size() < 95) return d;
    for (int f = 0; f < 50; f += 5) d.train.push_back(orb_descriptors(d.files[0][f]));
    for (int f = 0; f < 250; f += 25) d.train.push_back(orb_descriptors(d.files[1][f]));
    const auto t0 = std::chrono::steady_clock::now();
    d.voc = Vocabulary::train(d.train, kK, kL, 7);
    d.train_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    d.ok = true;
    return d;
  }();
  return d;
}

#define REQUIRE_DATA()      \
  DYNAORB_REQUIRE_SHARED(); \
  if (!data().ok) GTEST_SKIP() << "KITTI 06 / EuRoC images not found";

// Fails on the first difference between two vocabularies' outputs.
void expect_same_outputs(const Vocabulary& a, const Vocabulary& b, double tol) {
  ASSERT_EQ(a.size(), b.size());
  ASSERT_EQ(a.node_count(), b.node_count());
  EXPECT_EQ(a.branching(), b.branching());
  EXPECT_EQ(a.depth(), b.depth());
  for (WordId w = 0; w < a.size(); ++w) {
    ASSERT_EQ(a.word_node(w), b.word_node(w));
    ASSERT_NEAR(a.word_weight(w), b.word_weight(w), tol * (1.0 + a.word_weight(w)));
  }
  for (const cv::Mat& d : data().train) {
    BowVector ba, bb;
    FeatureVector fa, fb;
    a.transform(d, ba, fa, 2);
    b.transform(d, bb, fb, 2);
    ASSERT_EQ(ba.size(), bb.size());
    for (auto ia = ba.begin(), ib = bb.begin(); ia != ba.end(); ++ia, ++ib) {
      ASSERT_EQ(ia->first, ib->first);
      ASSERT_NEAR(ia->second, ib->second, tol);
    }
    ASSERT_EQ(fa, fb);
  }
}

// Expects a std::runtime_error whose message contains every piece.
template <typename F>
void expect_error(F f, const std::vector<std::string>& pieces) {
  try {
    f();
    ADD_FAILURE() << "no exception; expected one mentioning " << pieces.front();
  } catch (const std::runtime_error& e) {
    for (const std::string& p : pieces)
      EXPECT_NE(std::string(e.what()).find(p), std::string::npos) << e.what() << " lacks " << p;
  }
}

std::string read_bytes(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return std::string{std::istreambuf_iterator<char>(f), {}};
}

// An ORBvoc.txt node line whose 32 descriptor bytes are all `byte`.
std::string node_line(int parent, int leaf, int byte, double w) {
  std::string s = std::to_string(parent) + " " + std::to_string(leaf);
  for (int j = 0; j < 32; ++j) s += " " + std::to_string(byte);
  return s + " " + std::to_string(w) + "\n";
}

TEST(Vocabulary, TrainsBoundedTreeAndL1NormalisedVectors) {
  REQUIRE_DATA();
  const Vocabulary& voc = data().voc;
  std::size_t n_desc = 0;
  for (const cv::Mat& d : data().train) n_desc += d.rows;
  std::printf("[ vocab    ] trained k=%d L=%d on %zu images (%zu descriptors): %zu words, "
              "%zu nodes in %.3f s\n", kK, kL, data().train.size(), n_desc, voc.size(),
              voc.node_count(), data().train_s);
  EXPECT_EQ(voc.branching(), kK);
  EXPECT_EQ(voc.depth(), kL);
  EXPECT_GT(voc.size(), 2000u);
  EXPECT_LE(voc.size(), 10000u);  // k^L
  int positive = 0;
  for (WordId w = 0; w < voc.size(); ++w) {
    EXPECT_TRUE(voc.is_leaf(voc.word_node(w)));
    positive += voc.word_weight(w) > 0.0;
  }
  EXPECT_GT(positive, static_cast<int>(voc.size()) / 2);
  for (const cv::Mat& d : data().train) {
    for (int r = 0; r < d.rows; ++r) ASSERT_LT(voc.transform(d.ptr<std::uint8_t>(r)), voc.size());
    BowVector bow;
    voc.transform(d, bow);
    ASSERT_FALSE(bow.empty());
    EXPECT_NEAR(bow.l1_norm(), 1.0, 1e-9);
    for (const auto& [w, v] : bow) EXPECT_GT(v, 0.0);
    EXPECT_NEAR(voc.score(bow, bow), 1.0, 1e-9);
  }
}

TEST(Vocabulary, IdfIsLogOfImageFrequency) {
  REQUIRE_DATA();
  const Vocabulary& voc = data().voc;
  std::vector<int> n_images(voc.size(), 0);
  for (const cv::Mat& d : data().train) {
    std::set<WordId> seen;
    for (int r = 0; r < d.rows; ++r) seen.insert(voc.transform(d.ptr<std::uint8_t>(r)));
    for (WordId w : seen) ++n_images[w];
  }
  const double n = static_cast<double>(data().train.size());
  for (WordId w = 0; w < voc.size(); ++w)
    ASSERT_NEAR(voc.word_weight(w), n_images[w] ? std::log(n / n_images[w]) : 0.0, 1e-12) << w;
}

// Five well separated clusters (200 copies of a random centre, 3 random bits
// flipped in each): k-means++ seeding finds them (uniform seeding would fail
// most trials) and the majority vote recovers each centre exactly.
bool recovers_clusters(int trial) {
  cv::RNG rng(trial);
  cv::Mat centres(5, 32, CV_8U), d(1000, 32, CV_8U);
  rng.fill(centres, cv::RNG::UNIFORM, 0, 256);
  for (int i = 0; i < d.rows; ++i) {
    centres.row(i % 5).copyTo(d.row(i));
    for (int f = 0; f < 3; ++f) {
      const int bit = rng.uniform(0, 256);
      d.at<std::uint8_t>(i, bit / 8) ^= static_cast<std::uint8_t>(1u << (bit % 8));
    }
  }
  const Vocabulary voc = Vocabulary::train({d.rowRange(0, 500), d.rowRange(500, 1000)}, 5, 1,
                                           static_cast<unsigned>(trial));
  std::set<WordId> used;
  for (int c = 0; c < 5; ++c) {
    const WordId w = voc.transform(centres.ptr<std::uint8_t>(c));
    used.insert(w);
    if (std::memcmp(voc.node_descriptor(voc.word_node(w)), centres.ptr(c), 32) != 0) return false;
    for (int i = c; i < d.rows; i += 5)
      if (voc.transform(d.ptr<std::uint8_t>(i)) != w) return false;
  }
  return voc.size() == 5u && used.size() == 5u;
}

TEST(Vocabulary, KmeansRecoversBinaryClusters) {
  int ok = 0;
  for (int trial = 0; trial < 10; ++trial) ok += recovers_clusters(trial);
  EXPECT_GE(ok, 9);
}

// Images a = {d0, d1, d2, d0} and b = {d2, d3, d4, d4}: fewer than k distinct
// descriptors give one word each; d2 is in both images, so its IDF is 0.
TEST(Vocabulary, SmallTrainingSetGivesOneWordPerDistinctDescriptor) {
  cv::Mat d(5, 32, CV_8U), a, b;
  cv::RNG(3).fill(d, cv::RNG::UNIFORM, 0, 256);
  cv::vconcat(std::vector<cv::Mat>{d.row(0), d.row(1), d.row(2), d.row(0)}, a);
  cv::vconcat(std::vector<cv::Mat>{d.row(2), d.row(3), d.row(4), d.row(4)}, b);
  const Vocabulary voc = Vocabulary::train({a, b}, 10, 3);
  ASSERT_EQ(voc.size(), 5u);
  std::vector<NodeId> node(5);
  for (int r = 0; r < 5; ++r) {
    const WordId w = voc.transform(d.ptr<std::uint8_t>(r));
    node[r] = voc.word_node(w);
    EXPECT_EQ(std::memcmp(voc.node_descriptor(node[r]), d.ptr(r), 32), 0);
    EXPECT_NEAR(voc.word_weight(w), r == 2 ? 0.0 : std::log(2.0), 1e-12);
  }
  BowVector bow;
  FeatureVector fv;
  voc.transform(a, bow, fv, 0);  // weight-0 words stay out of bow, not out of fv
  ASSERT_EQ(bow.size(), 2u);
  EXPECT_NEAR(bow[voc.transform(d.ptr<std::uint8_t>(0))], 2.0 / 3.0, 1e-12);
  EXPECT_EQ(fv, (FeatureVector{{node[0], {0, 3}}, {node[1], {1}}, {node[2], {2}}}));
}

TEST(Vocabulary, TrainingIsDeterministicPerSeed) {
  REQUIRE_DATA();
  ScratchDir dir;
  const std::vector<cv::Mat> few(data().train.begin(), data().train.begin() + 4);
  auto trained = [&](unsigned seed) {
    const std::string p = (dir.path() / "voc.bin").string();
    Vocabulary::train(few, kK, 3, seed).save(p);
    return read_bytes(p);
  };
  EXPECT_EQ(trained(11), trained(11));
  EXPECT_NE(trained(11), trained(12));
}

TEST(Vocabulary, ScoreL1) {
  BowVector a{{1, 0.5}, {2, 0.5}}, b{{2, 3.0}}, c{{3, 1.0}}, empty;
  EXPECT_NEAR(score_l1(a, b), 0.5, 1e-12);  // b is normalised inside: {2: 1}
  EXPECT_NEAR(score_l1(b, a), 0.5, 1e-12);
  EXPECT_NEAR(score_l1(a, a), 1.0, 1e-12);
  EXPECT_EQ(score_l1(a, empty), 0.0);
  EXPECT_EQ(score_l1(a, c), 0.0);
  // With the norms given (what stored bags of words keep): the same value, bit for bit.
  const map::BagOfWords bag_a(a, {}), bag_b(b, {});
  EXPECT_EQ(bag_a.words_l1, 1.0);
  EXPECT_EQ(bag_b.words_l1, 3.0);
  EXPECT_EQ(score_l1(bag_a.words, bag_a.words_l1, bag_b.words, bag_b.words_l1), score_l1(a, b));
  EXPECT_EQ(score_l1(a, 0.0, b, 3.0), 0.0);  // an empty (zero-norm) side scores 0
  b.normalize_l1();
  EXPECT_NEAR(b[2], 1.0, 1e-12);
}

// Each query (database frame f + 1) against every database frame: the same
// place scores above every frame of another sequence, and the best database
// frame is the adjacent one for most queries.
TEST(Vocabulary, PlaceRecognition) {
  REQUIRE_DATA();
  const Vocabulary& voc = data().voc;
  std::vector<BowVector> db, queries;
  std::vector<int> seq;
  for (int si = 0; si < 3; ++si) {
    for (int f : data().database[si]) {
      BowVector b;
      voc.transform(orb_descriptors(data().files[si][f]), b);
      db.push_back(b);
      voc.transform(orb_descriptors(data().files[si][f + 1]), b);
      queries.push_back(b);
      seq.push_back(si);
    }
  }
  int hits = 0;
  for (std::size_t q = 0; q < queries.size(); ++q) {
    std::vector<double> s;
    double other = 0.0;
    for (std::size_t e = 0; e < db.size(); ++e) {
      s.push_back(voc.score(queries[q], db[e]));
      if (seq[e] != seq[q]) other = std::max(other, s.back());
    }
    std::printf("[ vocab    ] query %zu (sequence %d): adjacent frame %.3f, others <= %.3f\n", q,
                seq[q], s[q], other);
    EXPECT_GT(s[q], other) << "query " << q;
    const auto best = std::max_element(s.begin(), s.end()) - s.begin();
    hits += best == static_cast<std::ptrdiff_t>(q);
  }
  std::printf("[ vocab    ] nearest = adjacent frame for %d of %zu queries\n", hits,
              queries.size());
  EXPECT_GE(static_cast<double>(hits) / queries.size(), 0.85);
}

TEST(Vocabulary, FeatureVectorHoldsEveryFeatureOnce) {
  REQUIRE_DATA();
  const Vocabulary& voc = data().voc;
  const cv::Mat& d = data().train[3];
  for (int up : {0, 1, 2, kL, kL + 3}) {
    BowVector bow, plain;
    FeatureVector fv;
    voc.transform(d, bow, fv, up);
    std::vector<int> seen(d.rows, 0);
    for (const auto& [node, feats] : fv) {
      ASSERT_LT(node, voc.node_count());
      EXPECT_TRUE(std::is_sorted(feats.begin(), feats.end()));
      for (unsigned i : feats) {
        ASSERT_LT(i, static_cast<unsigned>(d.rows));
        ++seen[i];
        const WordId w = voc.transform(d.ptr<std::uint8_t>(i));
        EXPECT_EQ(node, voc.parent_at_level(w, up));
        EXPECT_TRUE(up != 0 || node == voc.word_node(w));
      }
    }
    for (int i = 0; i < d.rows; ++i) ASSERT_EQ(seen[i], 1) << "feature " << i << ", up " << up;
    EXPECT_TRUE(up < kL || fv.size() == 1u);   // everything under the root
    EXPECT_TRUE(up != 2 || fv.size() > 20u);   // depth-2 nodes
    voc.transform(d, plain);
    EXPECT_EQ(plain, bow);
  }
}

TEST(Vocabulary, BinaryRoundTrip) {
  REQUIRE_DATA();
  ScratchDir dir;
  const std::string path = (dir.path() / "voc.bin").string();
  data().voc.save(path);
  const auto t0 = std::chrono::steady_clock::now();
  const Vocabulary back = Vocabulary::load(path);
  std::printf("[ vocab    ] binary load of %zu nodes: %.2f ms\n", back.node_count(),
              1e3 * std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  expect_same_outputs(data().voc, back, 0.0);
  expect_same_outputs(data().voc, Vocabulary::load_any(path), 0.0);
}

TEST(Vocabulary, OrbvocTextRoundTrip) {
  REQUIRE_DATA();
  ScratchDir dir;
  const std::string path = (dir.path() / "ORBvoc.txt").string();
  data().voc.save_orbvoc_text(path);
  std::ifstream f(path);
  std::string header;
  std::getline(f, header);
  EXPECT_EQ(header, "10 4 0 0");
  expect_same_outputs(data().voc, Vocabulary::load_orbvoc_text(path), 1e-12);
  expect_same_outputs(data().voc, Vocabulary::load_any(path), 1e-12);
}

TEST(Vocabulary, HandWrittenOrbvoc) {
  ScratchDir dir;
  // k=2, L=1: word 0 = all-zero descriptor (weight 0.5), word 1 = all ones (1.25);
  // also with CRLF line ends, extra blanks and a blank line.
  const std::string text = "2 1 0 0\n" + node_line(0, 1, 0, 0.5) + node_line(0, 1, 255, 1.25);
  std::string crlf = "2  1\t0 0\n" + node_line(0, 1, 0, 0.5) + "\n" + node_line(0, 1, 255, 1.25);
  for (auto i = crlf.find('\n'); i != std::string::npos; i = crlf.find('\n', i + 2))
    crlf.insert(i, "\r");
  for (const std::string& t : {text, crlf}) {
    const Vocabulary voc = Vocabulary::load_any(dir.write("ORBvoc.txt", t).string());
    ASSERT_EQ(voc.size(), 2u);
    EXPECT_EQ(voc.node_count(), 3u);
    EXPECT_EQ(voc.branching(), 2);
    EXPECT_EQ(voc.depth(), 1);
    EXPECT_DOUBLE_EQ(voc.word_weight(0), 0.5);
    EXPECT_DOUBLE_EQ(voc.word_weight(1), 1.25);
    cv::Mat d = cv::Mat::zeros(3, 32, CV_8U);
    d.row(1).setTo(255);
    d.at<std::uint8_t>(0, 5) = 0x0F;  // 4 bits from word 0
    d.at<std::uint8_t>(1, 9) = 0x00;  // 8 bits from word 1
    d.at<std::uint8_t>(2, 0) = 0xFF;  // 8 bits from word 0
    BowVector bow;
    FeatureVector fv;
    voc.transform(d, bow, fv, 0);  // words 0, 1, 0: raw 0.5 * 2/3 and 1.25 * 1/3
    EXPECT_EQ(bow.size(), 2u);
    EXPECT_NEAR(bow[0], 1.0 / 2.25, 1e-12);
    EXPECT_NEAR(bow[1], 1.25 / 2.25, 1e-12);
    EXPECT_EQ(fv, (FeatureVector{{1, {0, 2}}, {2, {1}}}));
    voc.transform(d, bow, fv, 1);
    EXPECT_EQ(fv, (FeatureVector{{0, {0, 1, 2}}}));
  }
}

TEST(Vocabulary, TextErrorsNameFileAndLine) {
  ScratchDir dir;
  const std::string leaf0 = node_line(0, 1, 0, 0.5), leaf1 = node_line(0, 1, 255, 1.0);
  auto load = [&](const std::string& text) {
    const std::string p = dir.write("bad_voc.txt", text).string();
    return [p] { Vocabulary::load_orbvoc_text(p); };
  };
  const std::string missing = (dir.path() / "no_such_voc.txt").string();
  expect_error([&] { Vocabulary::load_orbvoc_text(missing); }, {"no_such_voc.txt", "cannot open"});
  expect_error([&] { Vocabulary::load_any(missing); }, {"no_such_voc.txt", "cannot open"});
  expect_error(load(""), {"bad_voc.txt:1:", "header"});
  expect_error(load("10 6 0\n" + leaf0), {"bad_voc.txt:1:", "4 fields"});
  expect_error(load("10 six 0 0\n" + leaf0), {"bad_voc.txt:1:", "six"});
  expect_error(load("1 6 0 0\n" + leaf0), {"bad_voc.txt:1:", "branching"});
  expect_error(load("10 0 0 0\n" + leaf0), {"bad_voc.txt:1:", "depth"});
  expect_error(load("10 6 2 0\n" + leaf0), {"bad_voc.txt:1:", "scoring", "CHI_SQUARE"});
  expect_error(load("10 6 0 1\n" + leaf0), {"bad_voc.txt:1:", "weighting", "TF"});
  expect_error(load("2 1 0 0\n" + leaf0 + "0 1 1 2 3 0.5\n"), {"bad_voc.txt:3:", "found 6"});
  expect_error(load("2 1 0 0\n" + leaf0 + node_line(5, 1, 3, 0.5)),
               {"bad_voc.txt:3:", "parent id 5 out of range"});
  expect_error(load("2 1 0 0\n" + node_line(0, 2, 0, 0.5)), {"bad_voc.txt:2:", "is_leaf"});
  expect_error(load("2 1 0 0\n" + node_line(0, 1, 256, 0.5)), {"bad_voc.txt:2:", "byte"});
  expect_error(load("2 1 0 0\n" + node_line(0, 1, 1, -2.0)), {"bad_voc.txt:2:", "weight"});
  expect_error(load("2 1 0 0\n" + leaf0 + leaf1 + node_line(1, 1, 3, 0.5)),
               {"bad_voc.txt:4:", "is a leaf"});
  expect_error(load("2 2 0 0\n" + node_line(0, 0, 0, 0.0) + leaf1),
               {"bad_voc.txt:2:", "without children"});
  expect_error(load("2 1 0 0\n" + leaf0 + leaf1 + leaf1), {"bad_voc.txt:4:", "more than k"});
  expect_error(load("2 1 0 0\n" + node_line(0, 0, 0, 0.0) + node_line(1, 1, 3, 0.5)),
               {"bad_voc.txt:3:", "depth 2 > L = 1"});
  expect_error(load("2 1 0 0\n\n"), {"bad_voc.txt", "no nodes"});
}

TEST(Vocabulary, BinaryErrorsNameFile) {
  ScratchDir dir;
  const std::string text = "2 1 0 0\n" + node_line(0, 1, 0, 0.5) + node_line(0, 1, 255, 1.25);
  const std::string path = (dir.path() / "tiny_voc.bin").string();
  Vocabulary::load_orbvoc_text(dir.write("tiny.txt", text).string()).save(path);
  const std::string bytes = read_bytes(path);
  ASSERT_EQ(bytes.size(), 32u + 3u * 45u);  // header + 3 nodes
  auto write = [&](const std::string& name, const std::string& b) {
    const std::string p = (dir.path() / name).string();
    std::ofstream(p, std::ios::binary) << b;
    return p;
  };
  expect_error([&] { Vocabulary::load((dir.path() / "absent.bin").string()); },
               {"absent.bin", "cannot open"});
  expect_error([&] { Vocabulary::load((dir.path() / "tiny.txt").string()); },
               {"tiny.txt", "DYNVOCAB"});
  for (std::size_t cut : {std::size_t{5}, std::size_t{20}, bytes.size() / 2, bytes.size() - 1}) {
    const std::string p = write("cut_voc.bin", bytes.substr(0, cut));
    expect_error([&] { Vocabulary::load(p); }, {"cut_voc.bin", cut < 8 ? "DYNVOCAB" : "truncated"});
    if (cut >= 8) expect_error([&] { Vocabulary::load_any(p); }, {"cut_voc.bin", "truncated"});
  }
  std::string v2 = bytes, parent7 = bytes;
  v2[8] = 2;
  parent7[32 + 4 * 2] = 7;  // node 2's parent
  expect_error([&] { Vocabulary::load(write("v2_voc.bin", v2)); }, {"v2_voc.bin", "version 2"});
  expect_error([&] { Vocabulary::load(write("long_voc.bin", bytes + "x")); },
               {"long_voc.bin", "unexpected bytes"});
  expect_error([&] { Vocabulary::load(write("par_voc.bin", parent7)); },
               {"par_voc.bin", "node 2", "parent id 7"});
  EXPECT_DOUBLE_EQ(Vocabulary::load(path).word_weight(1), 1.25);
}

TEST(Vocabulary, RejectsBadArguments) {
  const cv::Mat d = cv::Mat::zeros(4, 32, CV_8U);
  EXPECT_THROW(Vocabulary::train({d}, 1, 3), std::invalid_argument);
  EXPECT_THROW(Vocabulary::train({d}, 10, 0), std::invalid_argument);
  EXPECT_THROW(Vocabulary::train({cv::Mat::zeros(4, 32, CV_32F)}, 10, 3), std::invalid_argument);
  EXPECT_THROW(Vocabulary::train({cv::Mat()}, 10, 3), std::invalid_argument);
  Vocabulary empty;
  BowVector bow;
  FeatureVector fv;
  EXPECT_TRUE(empty.empty());
  EXPECT_THROW(empty.transform(d, bow), std::logic_error);
  cv::Mat two = cv::Mat::zeros(2, 32, CV_8U);
  two.row(1).setTo(255);
  const Vocabulary voc = Vocabulary::train({two}, 10, 3);
  EXPECT_EQ(voc.size(), 2u);
  EXPECT_THROW(voc.transform(cv::Mat::zeros(3, 16, CV_8U), bow), std::invalid_argument);
  EXPECT_THROW(voc.transform(d, bow, fv, -1), std::invalid_argument);
  voc.transform(cv::Mat(), bow, fv, 1);
  EXPECT_TRUE(bow.empty() && fv.empty());
}

}  // namespace
}  // namespace dynaorb
