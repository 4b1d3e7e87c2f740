#include "sketch/raster.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <functional>

namespace rheo::sketch::internal {
namespace {

// Neighbour bits, clockwise from north as in Hilditch's p2..p9 (y down):
// bit0 N (p2), bit1 NE (p3), bit2 E (p4), bit3 SE (p5), bit4 S (p6), bit5 SW (p7), bit6 W (p8),
// bit7 NW (p9).
struct Tables {
  std::array<uint8_t, 256> a{};   // 0->1 transitions in p2..p9,p2
  std::array<uint8_t, 256> b{};   // number of ink neighbours
  std::array<uint8_t, 256> n8{};  // Yokoi 8-connectivity number
  Tables() {
    for (int m = 0; m < 256; ++m) {
      int t = 0;
      for (int k = 0; k < 8; ++k) {
        if (!((m >> k) & 1) && ((m >> ((k + 1) % 8)) & 1)) ++t;
      }
      a[m] = static_cast<uint8_t>(t);
      b[m] = static_cast<uint8_t>(std::popcount(static_cast<unsigned>(m)));
      // Yokoi: x1..x8 counter-clockwise from east; sum over the 4-neighbours k of
      // xbar_k - xbar_k xbar_{k+1} xbar_{k+2}.
      const int e = (m >> 2) & 1, ne = (m >> 1) & 1, no = m & 1, nw = (m >> 7) & 1;
      const int w = (m >> 6) & 1, sw = (m >> 5) & 1, so = (m >> 4) & 1, se = (m >> 3) & 1;
      const int x[9] = {e, ne, no, nw, w, sw, so, se, e};
      int c = 0;
      for (int k = 0; k < 8; k += 2) {
        const int x0 = 1 - x[k], x1 = 1 - x[k + 1], x2 = 1 - x[(k + 2) % 8];
        c += x0 - x0 * x1 * x2;
      }
      n8[m] = static_cast<uint8_t>(c);
    }
  }
};
const Tables& T() {
  static const Tables t;
  return t;
}

// Offsets of p2..p9 in a bitmap with the given stride.
std::array<int, 8> Offsets(int s) {
  return {-s, -s + 1, 1, s + 1, s, s - 1, -1, -s - 1};
}

inline unsigned MaskOf(const uint8_t* v, int i, const std::array<int, 8>& off, uint8_t bits) {
  unsigned m = 0;
  for (int k = 0; k < 8; ++k) m |= unsigned((v[i + off[k]] & bits) != 0) << k;
  return m;
}

}  // namespace

int64_t Bitmap::Count() const {
  int64_t c = 0;
  for (uint8_t x : v) c += x != 0;
  return c;
}

int OtsuThreshold(const uint32_t (&h)[256]) {
  double total = 0, sum = 0;
  for (int i = 0; i < 256; ++i) total += h[i], sum += double(i) * h[i];
  double w0 = 0, sum0 = 0, best = -1;
  int t = 127;
  for (int i = 0; i < 256; ++i) {
    w0 += h[i];
    sum0 += double(i) * h[i];
    const double w1 = total - w0;
    if (w0 == 0 || w1 == 0) continue;
    const double m0 = sum0 / w0, m1 = (sum - sum0) / w1;
    const double between = w0 * w1 * (m0 - m1) * (m0 - m1);
    if (between > best) best = between, t = i;
  }
  return t;
}

Bitmap Binarize(const GrayImage& img, const ContourOptions& o, std::string* description,
                std::vector<std::string>* warnings) {
  const int w = img.width, h = img.height;
  const uint8_t* px = img.pixels.data();
  // Histograms of the whole picture and of an 8 x 8 grid of blocks (paper brightness per block).
  constexpr int kGrid = 8;
  std::vector<std::array<uint32_t, 256>> blocks(kGrid * kGrid, std::array<uint32_t, 256>{});
  uint32_t hist[256] = {};
  std::vector<int> bx(w);
  for (int x = 0; x < w; ++x) bx[x] = x * kGrid / w;
  // Statistics only: every second row and column is plenty above a megapixel.
  const int step = int64_t(w) * h > (1 << 20) ? 2 : 1;
  for (int y = 0; y < h; y += step) {
    auto* brow = &blocks[y * kGrid / h * kGrid];
    const uint8_t* row = px + size_t(y) * w;
    for (int x = 0; x < w; x += step) ++brow[bx[x]][row[x]];
  }
  for (const auto& b : blocks)
    for (int i = 0; i < 256; ++i) hist[i] += b[i];
  const int t = OtsuThreshold(hist);
  // Paper level per block: its 90th percentile; uneven light shows as spread among paper blocks.
  std::vector<int> p90s;
  for (const auto& b : blocks) {
    uint64_t n = 0;
    for (uint32_t c : b) n += c;
    if (n == 0) continue;
    uint64_t acc = 0;
    int p90 = 255;
    for (int i = 0; i < 256; ++i) {
      acc += b[i];
      if (acc * 10 >= n * 9) {
        p90 = i;
        break;
      }
    }
    p90s.push_back(p90);
  }
  // Paper blocks: those above the Otsu threshold, and below it those that continue the paper
  // levels without a jump. A block filled with ink (a silhouette) lies a jump below the paper;
  // paper in shadow continues it. Otsu alone splits a photo's paper when its light falls off:
  // the ink is a few percent of the pixels, the shadowed half of the paper becomes "ink".
  constexpr int kPaperStep = 16;  // largest step between paper levels in smooth light
  std::sort(p90s.begin(), p90s.end(), std::greater<int>());
  int lo = 255, hi = 0;
  for (size_t k = 0; k < p90s.size(); ++k) {
    const bool continues = k > 0 && p90s[k - 1] - p90s[k] <= kPaperStep && lo == p90s[k - 1];
    if (p90s[k] > t || continues) lo = std::min(lo, p90s[k]), hi = std::max(hi, p90s[k]);
  }
  Binarization mode = o.binarization;
  if (mode == Binarization::kAuto) {
    mode = (hi - lo > 40) ? Binarization::kAdaptive : Binarization::kOtsu;
  }
  Bitmap out(w, h);
  if (mode == Binarization::kOtsu) {
    // Light ink on dark paper: the frame of the picture is mostly paper.
    uint64_t dark = 0, n = 0;
    for (int x = 0; x < w; ++x) dark += (px[x] <= t) + (px[size_t(h - 1) * w + x] <= t), n += 2;
    for (int y = 0; y < h; ++y)
      dark += (px[size_t(y) * w] <= t) + (px[size_t(y) * w + w - 1] <= t), n += 2;
    const bool invert = dark * 2 > n;
    if (invert && warnings) warnings->push_back("light ink on dark paper: picture inverted");
    for (int y = 0; y < h; ++y) {
      const uint8_t* row = px + size_t(y) * w;
      uint8_t* dst = &out.v[out.Index(0, y)];
      if (invert) {
        for (int x = 0; x < w; ++x) dst[x] = row[x] > t;
      } else {
        for (int x = 0; x < w; ++x) dst[x] = row[x] <= t;
      }
    }
    *description = "otsu(t=" + std::to_string(t) + ")";
    return out;
  }
  // Adaptive (Bradley-Roth): ink when darker than the local mean by adaptive_offset.
  int win = o.adaptive_window_px > 0 ? o.adaptive_window_px : std::max(15, std::min(w, h) / 8);
  win |= 1;
  const int r = win / 2;
  // Sums modulo 2^32: window sums (< 2^32) come out exact from wrapped differences.
  std::vector<uint32_t> integral(size_t(w + 1) * (h + 1), 0);
  for (int y = 0; y < h; ++y) {
    uint32_t run = 0;
    const uint8_t* row = px + size_t(y) * w;
    uint32_t* dst = &integral[size_t(y + 1) * (w + 1) + 1];
    const uint32_t* above = &integral[size_t(y) * (w + 1) + 1];
    for (int x = 0; x < w; ++x) run += row[x], dst[x] = above[x] + run;
  }
  const int keep = static_cast<int>(std::lround(1024 * (1.0 - o.adaptive_offset)));
  for (int y = 0; y < h; ++y) {
    const int y0 = std::max(0, y - r), y1 = std::min(h, y + r + 1);
    const uint32_t* top = &integral[size_t(y0) * (w + 1)];
    const uint32_t* bot = &integral[size_t(y1) * (w + 1)];
    const uint8_t* row = px + size_t(y) * w;
    uint8_t* dst = &out.v[out.Index(0, y)];
    auto at = [&](int x) {
      const int x0 = std::max(0, x - r), x1 = std::min(w, x + r + 1);
      const uint32_t sum = bot[x1] - bot[x0] - top[x1] + top[x0];
      const uint64_t count = uint64_t(x1 - x0) * (y1 - y0);
      dst[x] = uint64_t(row[x]) * count * 1024 < uint64_t(sum) * keep;
    };
    const int mid0 = std::min(w, r), mid1 = std::max(mid0, w - r - 1);
    for (int x = 0; x < mid0; ++x) at(x);
    // Away from the sides the window is whole: no clamping, a constant count.
    const uint64_t c = uint64_t(2 * r + 1) * (y1 - y0) * 1024;
    for (int x = mid0; x < mid1; ++x) {
      const uint32_t sum = bot[x + r + 1] - bot[x - r] - top[x + r + 1] + top[x - r];
      dst[x] = row[x] * c < uint64_t(sum) * keep;
    }
    for (int x = mid1; x < w; ++x) at(x);
  }
  *description = "adaptive(w=" + std::to_string(win) + ")";
  return out;
}

int HilditchThin(Bitmap& bm, const CancelToken& cancel) {
  const auto& tb = T();
  const int s = bm.stride;
  const auto off = Offsets(s);
  uint8_t* v = bm.v.data();
  // Pixel bits: 1 ink now, 2 deleted in this pass (ink for the border conditions), 0x80 listed.
  constexpr uint8_t kListed = 0x80;
  std::vector<int> cand, next, deleted;
  for (int y = 0; y < bm.height; ++y) {
    const int row = bm.Index(0, y);
    for (int x = 0; x < bm.width; ++x) {
      const int i = row + x;
      if (v[i] == 1 && MaskOf(v, i, off, 1) != 0xFF) cand.push_back(i), v[i] |= kListed;
    }
  }
  int passes = 0;
  // Interior pixels (all 8 neighbours ink) can never go, so the list holds every pixel that
  // might: last pass's survivors plus the neighbours of its deletions.
  for (;;) {
    if (cancel.stop_requested()) break;
    ++passes;
    deleted.clear();
    next.clear();
    for (int i : cand) {
      const unsigned m_old = MaskOf(v, i, off, 3);
      const int b = tb.b[m_old];
      bool del = b >= 2 && b <= 6 && tb.a[m_old] == 1;
      if (del) {
        const bool p2 = m_old & 1, p4 = m_old & 4, p6 = m_old & 16, p8 = m_old & 64;
        if (p2 && p4 && p8 && tb.a[MaskOf(v, i + off[0], off, 3)] == 1) del = false;
        if (p2 && p4 && p6 && tb.a[MaskOf(v, i + off[2], off, 3)] == 1) del = false;
      }
      if (del) {
        // Sequential topology guard on the current picture: simple and not an end point.
        const unsigned m_cur = MaskOf(v, i, off, 1);
        del = tb.n8[m_cur] == 1 && tb.b[m_cur] >= 2;
      }
      if (del) {
        v[i] = 2;
        deleted.push_back(i);
      } else if (b < 8) {
        next.push_back(i);
      } else {
        v[i] &= ~kListed;
      }
    }
    if (deleted.empty()) break;
    for (int i : deleted) v[i] = 0;
    for (int i : deleted) {
      for (int d : off) {
        const int j = i + d;
        if (v[j] == 1) v[j] |= kListed, next.push_back(j);
      }
    }
    cand.swap(next);
  }
  for (int i : next) v[i] &= 1;
  return passes;
}

int ConnectivityNumber(const Bitmap& bm, int x, int y) {
  return T().n8[MaskOf(bm.v.data(), bm.Index(x, y), Offsets(bm.stride), 1)];
}

int64_t RemoveSpurs(Bitmap& bm, const CancelToken& cancel) {
  const auto& tb = T();
  const int s = bm.stride;
  const auto off = Offsets(s);
  const int four[4] = {-s, 1, s, -1};
  uint8_t* v = bm.v.data();
  const int n = static_cast<int>(bm.v.size());
  constexpr uint8_t kListed = 0x80;
  std::vector<int> cand, next;
  for (int i = 0; i < n; ++i)
    if (v[i] == 1) cand.push_back(i);
  // A background pixel whose four 4-neighbours are all ink: a one-pixel hole.
  auto one_pixel_hole = [&](int j) {
    if (v[j] != 0) return false;
    const int x = j % s, y = j / s;
    if (x == 0 || y == 0 || x == s - 1 || y == bm.height + 1) return false;
    for (int d : four)
      if ((v[j + d] & 1) == 0) return false;
    return true;
  };
  int64_t removed = 0;
  // Rescan until nothing changes; only pixels near a deletion can change their status.
  while (!cand.empty()) {
    if (cancel.stop_requested()) break;
    next.clear();
    for (int i : cand) {
      v[i] &= ~kListed;
      if (v[i] != 1) continue;
      const unsigned m = MaskOf(v, i, off, 1);
      const int c = tb.n8[m];
      bool del = tb.b[m] == 0 || c == 1;
      if (!del && (c == 2 || c == 3)) {
        for (int d : four) del = del || one_pixel_hole(i + d);
      }
      if (!del) continue;
      v[i] = 0;
      ++removed;
      for (int dy = -2; dy <= 2; ++dy) {
        for (int dx = -2; dx <= 2; ++dx) {
          const int j = i + dy * s + dx;
          if (j >= 0 && j < n && v[j] == 1) v[j] |= kListed, next.push_back(j);
        }
      }
    }
    std::sort(next.begin(), next.end());
    cand.swap(next);
  }
  return removed;
}

void FillEnclosed(Bitmap& bm, uint8_t fill) {
  // Mark the outside (4-connected zeros reachable from the frame), then swap labels.
  constexpr uint8_t kOut = 0xFE;
  SpanFill<false>(bm, 0, 0, kOut, [](int, int, int, int) {});
  for (auto& x : bm.v) x = x == kOut ? 0 : (x == 0 ? fill : x);
}

std::vector<std::pair<int, int>> TraceOuterBoundary(const Bitmap& bm) {
  std::vector<std::pair<int, int>> chain;
  const int s = bm.stride;
  const uint8_t* v = bm.v.data();
  int start = -1;
  for (int i = 0; i < static_cast<int>(bm.v.size()); ++i) {
    if (v[i]) {
      start = i;
      break;
    }
  }
  if (start < 0) return chain;
  // Directions clockwise on screen (y down): E, SE, S, SW, W, NW, N, NE.
  const int dx[8] = {1, 1, 0, -1, -1, -1, 0, 1};
  const int dy[8] = {0, 1, 1, 1, 0, -1, -1, -1};
  int dir_off[8];
  for (int k = 0; k < 8; ++k) dir_off[k] = dy[k] * s + dx[k];
  auto push = [&](int i) { chain.emplace_back(i % s - 1, i / s - 1); };
  push(start);
  int cur = start;
  int back = 4;  // direction from cur to the background pixel we came from (west of start)
  int first_next = -1;
  const size_t limit = 4 * bm.v.size() + 8;
  for (size_t step = 0; step < limit; ++step) {
    int found = -1;
    for (int k = 1; k <= 8; ++k) {
      const int d = (back + k) % 8;
      if (v[cur + dir_off[d]]) {
        found = d;
        break;
      }
    }
    if (found < 0) break;  // a single pixel
    const int nxt = cur + dir_off[found];
    // Jacob's stopping criterion: back at the start and about to repeat the first step.
    if (step > 0 && cur == start && nxt == first_next) break;
    if (step == 0) first_next = nxt;
    // The pixel checked just before `found` is background; seen from nxt it is the new back.
    const int bpos = cur + dir_off[(found + 7) % 8];
    const int ddx = (bpos % s) - (nxt % s), ddy = (bpos / s) - (nxt / s);
    for (int d = 0; d < 8; ++d)
      if (dx[d] == ddx && dy[d] == ddy) back = d;
    cur = nxt;
    push(cur);
  }
  if (chain.size() > 1 && chain.back() == chain.front()) chain.pop_back();
  return chain;
}

}  // namespace rheo::sketch::internal
