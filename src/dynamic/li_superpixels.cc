#include "dynaorb/dynamic/li_superpixels.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

namespace dynaorb::dynamic {

namespace {

// Per-cluster sums, kept up to date as pixels move, so that step 3 costs
// O(K) instead of a pass over every pixel.
struct Sums {
  std::vector<double> n, x, y, g;
  void move(int from, int to, int px, int py, int grey) {
    n[from] -= 1, x[from] -= px, y[from] -= py, g[from] -= grey;
    n[to] += 1, x[to] += px, y[to] += py, g[to] += grey;
  }
};

struct Centre {
  float x, y, g;
};

// Unstable pixels travel as (y << 16 | x): no division to recover x and y.
constexpr int kShift = 16;
constexpr int kMaxSide = 1 << kShift;

}  // namespace

LiSuperpixels li_slic(const cv::Mat& grey, double step, double nc, int max_iterations) {
  LiSuperpixels out;
  if (grey.empty() || grey.type() != CV_8UC1 || !(step >= 1.0) || !(nc > 0) || grey.cols >= kMaxSide ||
      grey.rows >= kMaxSide)
    return out;
  const int W = grey.cols, H = grey.rows;
  const int nx = std::max(1, static_cast<int>(std::lround(W / step)));
  const int ny = std::max(1, static_cast<int>(std::lround(H / step)));
  const int K = nx * ny;
  out.count = K;
  out.labels.create(H, W, CV_32SC1);
  int* L = out.labels.ptr<int>(0);  // continuous: just created

  // Step 1: grid cells as the first clusters.
  Sums s;
  s.n.assign(K, 0), s.x.assign(K, 0), s.y.assign(K, 0), s.g.assign(K, 0);
  std::vector<int> col_of(W);
  for (int x = 0; x < W; ++x) col_of[x] = std::min(nx - 1, x * nx / W);
  for (int y = 0; y < H; ++y) {
    const int row = std::min(ny - 1, y * ny / H) * nx;
    const uchar* g = grey.ptr<uchar>(y);
    for (int x = 0; x < W; ++x) {
      const int k = row + col_of[x];
      L[y * W + x] = k;
      s.n[k] += 1, s.x[k] += x, s.y[k] += y, s.g[k] += g[x];
    }
  }
  std::vector<double> cx(K), cy(K), cg(K);
  auto update_centres = [&] {
    for (int k = 0; k < K; ++k) {
      if (s.n[k] <= 0) continue;  // an emptied cluster is left out of the buckets
      cx[k] = s.x[k] / s.n[k], cy[k] = s.y[k] / s.n[k], cg[k] = s.g[k] / s.n[k];
    }
  };
  update_centres();

  std::vector<uint8_t> flag(static_cast<size_t>(W) * H, 0), changed(static_cast<size_t>(W) * H, 0);
  std::vector<int> unstable, next;
  auto mark = [&](int x, int y) {
    const int p = y * W + x;
    if (!flag[p]) {
      flag[p] = 1;
      next.push_back(y << kShift | x);
    }
  };
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const int p = y * W + x;
      if (x + 1 < W && L[p] != L[p + 1]) mark(x, y), mark(x + 1, y);
      if (y + 1 < H && L[p] != L[p + W]) mark(x, y), mark(x, y + 1);
    }
  unstable.swap(next);

  // Centres bucketed by position in cells at least S wide: every centre
  // within S of a pixel (the 2S x 2S window) is in the pixel's cell or one
  // of the 8 around it. Each cell lists the centres of its 3x3 block, so a
  // pixel scans one short contiguous list.
  const double bucket = std::max({step, static_cast<double>(W) / nx, static_cast<double>(H) / ny});
  const int bw = static_cast<int>(W / bucket) + 1, bh = static_cast<int>(H / bucket) + 1;
  std::vector<int> bucket_col(W), bucket_row(H);
  for (int x = 0; x < W; ++x) bucket_col[x] = std::min(bw - 1, static_cast<int>(x / bucket));
  for (int y = 0; y < H; ++y) bucket_row[y] = std::min(bh - 1, static_cast<int>(y / bucket)) * bw;
  std::vector<int> own_start(bw * bh + 1), own(K), cand_start(bw * bh + 1), cand_k;
  std::vector<Centre> cand_c;
  const float S = static_cast<float>(step);
  constexpr float kFar = std::numeric_limits<float>::max();
  const float inv_s2 = static_cast<float>(1.0 / (step * step)), inv_nc2 = static_cast<float>(1.0 / (nc * nc));

  for (int it = 0; it < max_iterations && !unstable.empty(); ++it) {
    std::fill(own_start.begin(), own_start.end(), 0);
    auto bucket_of = [&](int k) {
      const int bx = std::clamp(static_cast<int>(cx[k] / bucket), 0, bw - 1);
      const int by = std::clamp(static_cast<int>(cy[k] / bucket), 0, bh - 1);
      return by * bw + bx;
    };
    for (int k = 0; k < K; ++k)
      if (s.n[k] > 0) ++own_start[bucket_of(k) + 1];
    for (size_t b = 1; b < own_start.size(); ++b) own_start[b] += own_start[b - 1];
    {
      std::vector<int> cursor(own_start.begin(), own_start.end() - 1);
      for (int k = 0; k < K; ++k)
        if (s.n[k] > 0) own[cursor[bucket_of(k)]++] = k;
    }
    cand_c.clear();
    cand_k.clear();
    for (int by = 0; by < bh; ++by)
      for (int bx = 0; bx < bw; ++bx) {
        cand_start[by * bw + bx] = static_cast<int>(cand_k.size());
        for (int v = std::max(0, by - 1); v <= std::min(bh - 1, by + 1); ++v)
          for (int u = std::max(0, bx - 1); u <= std::min(bw - 1, bx + 1); ++u)
            for (int b = own_start[v * bw + u]; b < own_start[v * bw + u + 1]; ++b) {
              const int k = own[b];
              cand_k.push_back(k);
              cand_c.push_back({static_cast<float>(cx[k]), static_cast<float>(cy[k]), static_cast<float>(cg[k])});
            }
      }
    cand_start[bw * bh] = static_cast<int>(cand_k.size());

    // Step 2.
    int n_changed = 0;
    for (int e : unstable) {
      const int x = e & (kMaxSide - 1), y = e >> kShift, p = y * W + x;
      const int gi = grey.ptr<uchar>(y)[x];
      const float fx = static_cast<float>(x), fy = static_cast<float>(y), g = static_cast<float>(gi);
      const int b = bucket_row[y] + bucket_col[x];
      // Branch-free scan: which centres' windows hold the pixel is as good as
      // random, so a test-and-skip would mispredict about half the time.
      int best_c = -1;
      float best_d = kFar;
      for (int c = cand_start[b]; c < cand_start[b + 1]; ++c) {
        const Centre& ce = cand_c[c];
        const float dx = ce.x - fx, dy = ce.y - fy, dc = ce.g - g;
        float d = dc * dc * inv_nc2 + (dx * dx + dy * dy) * inv_s2;  // eq. 5, squared
        d = (std::abs(dx) <= S && std::abs(dy) <= S) ? d : kFar;      // only within 2S x 2S
        best_c = d < best_d ? c : best_c;
        best_d = std::min(d, best_d);
      }
      const int best = best_c >= 0 ? cand_k[best_c] : L[p];
      if (best != L[p]) {
        s.move(L[p], best, x, y, gi);
        L[p] = best;
        changed[p] = 1;
        ++n_changed;
      }
    }
    out.visits += static_cast<long long>(unstable.size());
    out.iterations = it + 1;
    if (n_changed == 0) {
      out.converged = true;
      break;
    }

    // Step 3: centres, then the flags of eq. 7 (a changed pixel also stays
    // unstable itself: its Flag_q is set).
    update_centres();
    for (int e : unstable) flag[(e >> kShift) * W + (e & (kMaxSide - 1))] = 0;
    next.clear();
    for (int e : unstable) {
      const int x = e & (kMaxSide - 1), y = e >> kShift, q = y * W + x, lq = L[q];
      const bool ch = changed[q] != 0;
      changed[q] = 0;
      if (ch) mark(x, y);
      if (x > 0 && (ch || L[q - 1] != lq)) mark(x - 1, y);
      if (x + 1 < W && (ch || L[q + 1] != lq)) mark(x + 1, y);
      if (y > 0 && (ch || L[q - W] != lq)) mark(x, y - 1);
      if (y + 1 < H && (ch || L[q + W] != lq)) mark(x, y + 1);
    }
    unstable.swap(next);
  }
  return out;
}

}  // namespace dynaorb::dynamic
