// Vocabulary files: ORB-SLAM2's ORBvoc.txt (DBoW2's text format) and our
// binary form. The text loader reads the whole file at once and parses with
// std::from_chars (ORBvoc.txt: ~1.1M lines of 35 fields); the binary form is
// a header and four flat arrays, read in one go.
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <string_view>

#include "dynaorb/io/errors.h"
#include "dynaorb/vocab/vocabulary.h"

namespace dynaorb::vocab {

using std::to_string;

namespace {

constexpr char kMagic[8] = {'D', 'Y', 'N', 'V', 'O', 'C', 'A', 'B'};
constexpr std::uint32_t kVersion = 1;
constexpr std::size_t kHeaderBytes = 8 + 6 * 4;
constexpr std::size_t kBytesPerNode = 4 + 1 + Vocabulary::kDescriptorBytes + 8;
constexpr int kMaxK = 1000, kMaxL = 20;
constexpr int kFieldsPerNode = 2 + Vocabulary::kDescriptorBytes + 1;

const char* scoring_name(long long s) {
  static const char* names[] = {"L1_NORM", "L2_NORM",       "CHI_SQUARE",
                                "KL",      "BHATTACHARYYA", "DOT_PRODUCT"};
  return (s >= 0 && s < 6) ? names[s] : "unknown";
}
const char* weighting_name(long long w) {
  static const char* names[] = {"TF_IDF", "TF", "IDF", "BINARY"};
  return (w >= 0 && w < 4) ? names[w] : "unknown";
}

std::string quoted(std::string_view s) { return "\"" + std::string(s) + "\""; }

// Throws InputError(path, line, ...) for a k, L, scoring or weighting we cannot use.
void check_params(const std::string& path, int line, long long k, long long L, long long scoring,
                  long long weighting) {
  if (k < 2 || k > kMaxK)
    throw InputError(path, line, "branching k = " + to_string(k) + " out of range [2, " +
                                     to_string(kMaxK) + "]");
  if (L < 1 || L > kMaxL)
    throw InputError(path, line, "depth L = " + to_string(L) + " out of range [1, " +
                                     to_string(kMaxL) + "]");
  if (scoring != 0)
    throw InputError(path, line, "unsupported scoring type " + to_string(scoring) + " (" +
                                     scoring_name(scoring) + "); only 0 (L1_NORM) is supported");
  if (weighting != 0)
    throw InputError(path, line, "unsupported weighting type " + to_string(weighting) + " (" +
                                     weighting_name(weighting) + "); only 0 (TF_IDF) is supported");
}

std::string read_all(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw InputError(path, 0, "cannot open the vocabulary file");
  f.seekg(0, std::ios::end);
  const std::streamoff size = f.tellg();
  if (size < 0) throw InputError(path, 0, "cannot read the vocabulary file");
  std::string data(static_cast<std::size_t>(size), '\0');
  f.seekg(0);
  if (size > 0 && !f.read(data.data(), size))
    throw InputError(path, 0, "cannot read the vocabulary file");
  return data;
}

void write_all(const std::string& path, const std::string& data) {
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  if (!f) throw InputError(path, 0, "cannot open the file for writing");
  f.write(data.data(), static_cast<std::streamsize>(data.size()));
  f.flush();
  if (!f) throw InputError(path, 0, "write failed");
}

bool is_space(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f'; }

// Splits a line at whitespace into at most max tokens; returns the total count.
int split(std::string_view line, std::string_view* tokens, int max) {
  int n = 0;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && is_space(line[i])) ++i;
    if (i == line.size()) break;
    const std::size_t b = i;
    while (i < line.size() && !is_space(line[i])) ++i;
    if (n < max) tokens[n] = line.substr(b, i - b);
    ++n;
  }
  return n;
}

template <typename T>
bool parse(std::string_view s, T& v) {
  const char* b = s.data();
  if (!s.empty() && *b == '+') ++b;  // from_chars takes no '+'
  const auto [p, ec] = std::from_chars(b, s.data() + s.size(), v);
  return ec == std::errc() && p == s.data() + s.size();
}

void put_u32(std::string& out, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) out.push_back(static_cast<char>((v >> (8 * i)) & 0xFF));
}
std::uint32_t get_u32(const char* p) {
  std::uint32_t v = 0;
  for (int i = 0; i < 4; ++i) v |= std::uint32_t{static_cast<unsigned char>(p[i])} << (8 * i);
  return v;
}

}  // namespace

// ---------------------------------------------------------------- ORBvoc.txt

Vocabulary Vocabulary::load_orbvoc_text(const std::string& path) {
  const std::string text = read_all(path);
  std::size_t pos = 0;
  int line_no = 0;
  auto next_line = [&](std::string_view& line) {
    if (pos >= text.size()) return false;
    std::size_t e = text.find('\n', pos);
    if (e == std::string::npos) e = text.size();
    line = std::string_view(text).substr(pos, e - pos);
    pos = e + 1;
    ++line_no;
    return true;
  };

  std::string_view line, tok[kFieldsPerNode];
  if (!next_line(line))
    throw InputError(path, 1, "empty file: expected the header \"k L scoring weighting\"");
  long long h[4];
  const int nh = split(line, tok, 4);
  if (nh != 4)
    throw InputError(path, 1, "header must be \"k L scoring weighting\" (4 fields), found " +
                                  to_string(nh) + " fields");
  for (int i = 0; i < 4; ++i)
    if (!parse(tok[i], h[i]))
      throw InputError(path, 1, "header field " + to_string(i + 1) + " " + quoted(tok[i]) +
                                    " is not an integer");
  check_params(path, 1, h[0], h[1], h[2], h[3]);

  Vocabulary v;
  v.k_ = static_cast<int>(h[0]);
  v.L_ = static_cast<int>(h[1]);
  const std::size_t guess = text.size() / 100 + 1;  // ORBvoc.txt: ~100 bytes a line
  v.parent_.reserve(guess);
  v.descriptors_.reserve(guess * kDescriptorBytes);
  std::vector<std::uint8_t> is_leaf;
  std::vector<double> weight;
  std::vector<int> line_of;  // per node
  is_leaf.reserve(guess);
  weight.reserve(guess);
  line_of.reserve(guess);
  v.parent_.push_back(kNoNode);  // the root, not in the file
  v.descriptors_.resize(kDescriptorBytes, 0);
  is_leaf.push_back(0);
  weight.push_back(0.0);
  line_of.push_back(1);

  while (next_line(line)) {
    const int n = split(line, tok, kFieldsPerNode);
    if (n == 0) continue;  // blank line
    if (n != kFieldsPerNode)
      throw InputError(path, line_no, "expected " + to_string(kFieldsPerNode) +
                                          " fields (parent, is_leaf, 32 descriptor bytes, "
                                          "weight), found " + to_string(n));
    const auto nid = static_cast<unsigned long long>(v.parent_.size());
    if (nid >= kNoNode) throw InputError(path, line_no, "too many nodes");
    unsigned long long parent = 0;
    if (!parse(tok[0], parent))
      throw InputError(path, line_no, "parent id " + quoted(tok[0]) + " is not an integer >= 0");
    if (parent >= nid)
      throw InputError(path, line_no, "parent id " + to_string(parent) + " out of range: node " +
                                          to_string(nid) + " may only have an earlier node (0.." +
                                          to_string(nid - 1) + ") as parent");
    int leaf = 0;
    if (!parse(tok[1], leaf) || (leaf != 0 && leaf != 1))
      throw InputError(path, line_no, "is_leaf " + quoted(tok[1]) + " must be 0 or 1");
    for (int j = 0; j < kDescriptorBytes; ++j) {
      int b = 0;
      if (!parse(tok[2 + j], b) || b < 0 || b > 255)
        throw InputError(path, line_no, "descriptor byte " + to_string(j) + " " +
                                            quoted(tok[2 + j]) + " is not an integer in [0, 255]");
      v.descriptors_.push_back(static_cast<std::uint8_t>(b));
    }
    double w = 0.0;
    if (!parse(tok[kFieldsPerNode - 1], w) || !std::isfinite(w) || w < 0.0)
      throw InputError(path, line_no, "weight " + quoted(tok[kFieldsPerNode - 1]) +
                                          " is not a finite number >= 0");
    v.parent_.push_back(static_cast<NodeId>(parent));
    is_leaf.push_back(static_cast<std::uint8_t>(leaf));
    weight.push_back(w);
    line_of.push_back(line_no);
  }
  NodeId bad = 0;
  std::string problem;
  if (!v.finish(is_leaf, weight, bad, problem)) throw InputError(path, line_of[bad], problem);
  return v;
}

void Vocabulary::save_orbvoc_text(const std::string& path) const {
  if (empty()) throw std::logic_error("Vocabulary::save_orbvoc_text: the vocabulary is empty");
  std::string out;
  out.reserve(node_count() * 110);
  out += std::to_string(k_) + " " + std::to_string(L_) + " " +
         std::to_string(static_cast<std::uint32_t>(scoring())) + " " +
         std::to_string(static_cast<std::uint32_t>(weighting())) + "\n";
  char buf[64];
  for (std::size_t i = 1; i < node_count(); ++i) {
    out += std::to_string(parent_[i]);
    out += is_leaf(static_cast<NodeId>(i)) ? " 1" : " 0";
    const std::uint8_t* d = node_descriptor(static_cast<NodeId>(i));
    for (int j = 0; j < kDescriptorBytes; ++j) {
      out += ' ';
      out += std::to_string(d[j]);
    }
    const double w = is_leaf(static_cast<NodeId>(i)) ? word_weight_[node_word_[i]] : 0.0;
    const auto r = std::to_chars(buf, buf + sizeof(buf), w);  // shortest exact form
    out += ' ';
    out.append(buf, r.ptr);
    out += '\n';
  }
  write_all(path, out);
}

// ---------------------------------------------------------------- binary

void Vocabulary::save(const std::string& path) const {
  if (empty()) throw std::logic_error("Vocabulary::save: the vocabulary is empty");
  const std::size_t n = node_count();
  std::string out;
  out.reserve(kHeaderBytes + n * kBytesPerNode);
  out.append(kMagic, sizeof(kMagic));
  put_u32(out, kVersion);
  put_u32(out, static_cast<std::uint32_t>(k_));
  put_u32(out, static_cast<std::uint32_t>(L_));
  put_u32(out, static_cast<std::uint32_t>(scoring()));
  put_u32(out, static_cast<std::uint32_t>(weighting()));
  put_u32(out, static_cast<std::uint32_t>(n));
  for (std::size_t i = 0; i < n; ++i) put_u32(out, parent_[i]);
  for (std::size_t i = 0; i < n; ++i) out.push_back(is_leaf(static_cast<NodeId>(i)) ? 1 : 0);
  out.append(reinterpret_cast<const char*>(descriptors_.data()), descriptors_.size());
  for (std::size_t i = 0; i < n; ++i) {
    const double w = is_leaf(static_cast<NodeId>(i)) ? word_weight_[node_word_[i]] : 0.0;
    std::uint64_t bits = 0;
    std::memcpy(&bits, &w, 8);
    for (int b = 0; b < 8; ++b) out.push_back(static_cast<char>((bits >> (8 * b)) & 0xFF));
  }
  write_all(path, out);
}

Vocabulary Vocabulary::load(const std::string& path) {
  const std::string data = read_all(path);
  if (data.size() < sizeof(kMagic) || std::memcmp(data.data(), kMagic, sizeof(kMagic)) != 0)
    throw InputError(path, 0,
                     "not a binary vocabulary (the file does not start with \"DYNVOCAB\")");
  if (data.size() < kHeaderBytes)
    throw InputError(path, 0, "truncated: " + to_string(data.size()) +
                                  " bytes, the header alone has " + to_string(kHeaderBytes));
  const char* p = data.data() + sizeof(kMagic);
  std::uint32_t h[6];
  for (int i = 0; i < 6; ++i) h[i] = get_u32(p + 4 * i);
  if (h[0] != kVersion)
    throw InputError(path, 0, "unsupported format version " + to_string(h[0]) + " (expected " +
                                  to_string(kVersion) + ")");
  check_params(path, 0, h[1], h[2], h[3], h[4]);
  const std::size_t n = h[5];
  const std::size_t expected = kHeaderBytes + n * kBytesPerNode;
  if (data.size() < expected)
    throw InputError(path, 0, "truncated: " + to_string(n) + " nodes need " + to_string(expected) +
                                  " bytes, the file has " + to_string(data.size()));
  if (data.size() > expected)
    throw InputError(path, 0, to_string(data.size() - expected) + " unexpected bytes after " +
                                  to_string(n) + " nodes");

  Vocabulary v;
  v.k_ = static_cast<int>(h[1]);
  v.L_ = static_cast<int>(h[2]);
  p = data.data() + kHeaderBytes;
  v.parent_.resize(n);
  for (std::size_t i = 0; i < n; ++i) v.parent_[i] = get_u32(p + 4 * i);
  p += 4 * n;
  const auto* u = reinterpret_cast<const std::uint8_t*>(p);
  std::vector<std::uint8_t> is_leaf(u, u + n);
  for (std::size_t i = 0; i < n; ++i)
    if (is_leaf[i] > 1)
      throw InputError(path, 0, "node " + to_string(i) + ": is_leaf must be 0 or 1");
  p += n;
  u += n;
  v.descriptors_.assign(u, u + n * kDescriptorBytes);
  p += n * kDescriptorBytes;
  std::vector<double> weight(n);
  for (std::size_t i = 0; i < n; ++i) {
    std::uint64_t bits = 0;
    for (int b = 0; b < 8; ++b)
      bits |= std::uint64_t{static_cast<unsigned char>(p[8 * i + b])} << (8 * b);
    std::memcpy(&weight[i], &bits, 8);
  }
  NodeId bad = 0;
  std::string problem;
  if (!v.finish(is_leaf, weight, bad, problem))
    throw InputError(path, 0, "node " + to_string(bad) + ": " + problem);
  return v;
}

Vocabulary Vocabulary::load_any(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw InputError(path, 0, "cannot open the vocabulary file");
  char head[sizeof(kMagic)] = {};
  f.read(head, sizeof(head));
  const bool binary = f.gcount() == static_cast<std::streamsize>(sizeof(head)) &&
                      std::memcmp(head, kMagic, sizeof(kMagic)) == 0;
  f.close();
  return binary ? load(path) : load_orbvoc_text(path);
}

}  // namespace dynaorb::vocab
