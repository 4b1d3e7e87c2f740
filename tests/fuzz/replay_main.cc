// Runs a fuzz target's LLVMFuzzerTestOneInput over a fixed, deterministic set of mutated inputs,
// so every test run exercises the decoders with hostile bytes, with or without libFuzzer, and
// it replays each file of the regression corpus (regressions/image or regressions/strokes) as is.
//   sketch_fuzz_replay_{image,strokes} [mutations_per_seed]
#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include "test_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size);

namespace {

using Bytes = std::vector<uint8_t>;
namespace t = rheo::sketch::testing;

// Recomputes every chunk CRC of a PNG, so mutations reach past libpng's CRC check.
void FixPngCrcs(Bytes& b) {
  size_t i = 8;
  while (i + 12 <= b.size()) {
    const uint32_t len = (uint32_t(b[i]) << 24) | (b[i + 1] << 16) | (b[i + 2] << 8) | b[i + 3];
    if (len > b.size() || i + 12 + len > b.size()) break;
    const uint32_t c = t::Crc32(&b[i + 4], len + 4);
    b[i + 8 + len] = c >> 24, b[i + 9 + len] = c >> 16, b[i + 10 + len] = c >> 8,
              b[i + 11 + len] = c;
    i += 12 + len;
  }
}

Bytes Mutate(const Bytes& seed, std::mt19937& rng, bool png, const std::vector<Bytes>& dict) {
  Bytes b = seed;
  std::uniform_int_distribution<int> op(0, 8);
  const int n_ops = 1 + static_cast<int>(rng() % 4);
  for (int k = 0; k < n_ops && !b.empty(); ++k) {
    const size_t at = rng() % b.size();
    switch (op(rng)) {
      case 0: b[at] ^= uint8_t(1u << (rng() % 8)); break;
      case 1: b[at] = uint8_t(rng()); break;
      case 2: b.resize(at); break;  // truncate
      case 3: b.erase(b.begin() + at, b.begin() + std::min(b.size(), at + 1 + rng() % 16)); break;
      case 4: b.insert(b.begin() + at, 1 + rng() % 8, uint8_t(rng())); break;
      case 5: {  // duplicate a range (overlong strokes, repeated chunks)
        const size_t len = std::min<size_t>(b.size() - at, 1 + rng() % 256);
        Bytes piece(b.begin() + at, b.begin() + at + len);
        b.insert(b.begin() + at, piece.begin(), piece.end());
        break;
      }
      case 6: {  // interesting values: 0, 0xFF, large sizes
        static const uint8_t kVals[] = {0x00, 0xFF, 0x7F, 0x80, 0x01, 0x40};
        for (size_t j = at; j < std::min(b.size(), at + 4); ++j) b[j] = kVals[rng() % 6];
        break;
      }
      case 7:
        if (!dict.empty()) {
          const Bytes& d = dict[rng() % dict.size()];
          b.insert(b.begin() + at, d.begin(), d.end());
        }
        break;
      default: std::swap(b[at], b[rng() % b.size()]); break;
    }
  }
  if (png && rng() % 2) FixPngCrcs(b);
  return b;
}

Bytes FromString(const std::string& s) {
  return Bytes(s.begin(), s.end());
}

}  // namespace

int main(int argc, char** argv) {
  const int per_seed = argc > 1 ? std::atoi(argv[1]) : 400;
  std::vector<Bytes> seeds;
  std::vector<Bytes> dict;
  bool png_kind = false;
#ifdef RHEO_FUZZ_IMAGE
  png_kind = true;
  {
    t::Picture p = t::Blank(96, 80);
    t::InkPolyline(p, t::Ellipse({48, 40}, 30, 25, 120), true, 3.0);
    seeds.push_back(t::EncodePng(p));
    seeds.push_back(t::EncodeJpeg(p, 75));
    t::Picture f = t::Blank(64, 64);
    t::FillPolygon(f, t::Star({32, 32}, 28, 16, 5, 200));
    seeds.push_back(t::EncodePng(f));
    seeds.push_back(t::EncodeJpeg(f, 50));
  }
  dict = {FromString("IHDR"), FromString("IDAT"), FromString("IEND"),
          {0xFF, 0xD8},       {0xFF, 0xC0},       {0xFF, 0xC2},
          {0xFF, 0xDA},       {0xFF, 0xD9},       {0x00, 0x00, 0x40, 0x00}};
#else
  {
    auto ring = t::Ellipse({100, 80}, 60, 40, 80);
    auto star = t::Star({100, 100}, 80, 40, 5, 120);
    std::vector<rheo::Vec2> a(ring.begin(), ring.begin() + 45), b(ring.begin() + 40, ring.end());
    b.push_back(ring[2]);
    seeds.push_back(FromString(t::StrokesJson(200, 200, {a, b})));
    star.push_back(star[0]);
    seeds.push_back(FromString(t::StrokesJson(200, 200, {star})));
    seeds.push_back(FromString(
        R"({"width":10,"height":10,"strokes":[[[1,1],[8,1],[8,8],[1,8],[1,1]]],"x":{"y":[1,{}]}})"));
  }
  dict = {FromString("[["),   FromString("]]"),           FromString(","),    FromString("1e308"),
          FromString("-0.5"), FromString("\"strokes\":"), FromString("null"), FromString("{}")};
#endif
  // Three of the project's sample sketches (samples/) as more seeds; they are always there.
  for (const char* name : {"bean", "letter_c", "star5"}) {
    const std::string path =
        std::string(RHEO_SKETCH_SAMPLES) + "/" + name + (png_kind ? ".png" : ".json");
    auto data = t::ReadFile(path);
    if (!data) {
      std::fprintf(stderr, "missing sample %s\n", path.c_str());
      return 1;
    }
    seeds.push_back(FromString(*data));
  }
  // The regression corpus: inputs libFuzzer once found (crashes, timeouts), each run as it is.
  std::vector<std::string> regressions;
  const std::filesystem::path corpus = RHEO_FUZZ_REGRESSIONS;
  if (std::filesystem::is_directory(corpus)) {
    for (const auto& e : std::filesystem::directory_iterator(corpus)) {
      if (e.is_regular_file()) regressions.push_back(e.path().string());
    }
  }
  std::sort(regressions.begin(), regressions.end());
  for (const std::string& path : regressions) {
    auto data = t::ReadFile(path);
    if (!data) {
      std::fprintf(stderr, "cannot read %s\n", path.c_str());
      return 1;
    }
    const Bytes b = FromString(*data);
    LLVMFuzzerTestOneInput(b.data(), b.size());
  }
  std::mt19937 rng(20240601u);
  int runs = 0;
  for (const Bytes& s : seeds) {
    LLVMFuzzerTestOneInput(s.data(), s.size());
    ++runs;
    for (int k = 0; k < per_seed; ++k) {
      const Bytes m = Mutate(s, rng, png_kind, dict);
      LLVMFuzzerTestOneInput(m.data(), m.size());
      ++runs;
    }
  }
  std::printf(
      "%d inputs (%zu seeds x %d mutations) and %zu regression inputs, no invariant broken\n", runs,
      seeds.size(), per_seed, regressions.size());
  return 0;
}
