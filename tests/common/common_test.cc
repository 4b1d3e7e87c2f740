#include <gtest/gtest.h>

#include "common/status.h"
#include "common/tet_mesh_io.h"

namespace rheo {
namespace {

TetMesh TwoTets() {
  TetMesh m;
  m.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {1, 1, 1}};
  m.tets = {{0, 1, 2, 3}, {1, 2, 3, 4}};
  for (auto& t : m.tets) {
    const Vec3& a = m.positions[t[0]];
    if ((m.positions[t[1]] - a).dot((m.positions[t[2]] - a).cross(m.positions[t[3]] - a)) < 0)
      std::swap(t[2], t[3]);
  }
  ComputeBoundary(m);
  return m;
}

TEST(TetMeshIo, VtuRoundTripKeepsEverything) {
  TetMesh m = TwoTets();
  EXPECT_EQ(m.surface.size(), 6u) << "two tets sharing a face have 6 boundary faces";
  Result<TetMesh> r = ReadVtu(WriteVtu(m));
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_EQ(r->positions.size(), m.positions.size());
  for (size_t i = 0; i < m.positions.size(); ++i) EXPECT_EQ(r->positions[i], m.positions[i]);
  EXPECT_EQ(r->tets, m.tets);
  EXPECT_EQ(r->surface.size(), 6u);
}

TEST(TetMeshIo, BoundaryFacesPointOutward) {
  TetMesh m = TwoTets();
  Vec3 c = Vec3::Zero();
  for (auto& p : m.positions) c += p;
  c /= static_cast<double>(m.positions.size());
  for (auto& f : m.surface) {
    Vec3 n = (m.positions[f[1]] - m.positions[f[0]]).cross(m.positions[f[2]] - m.positions[f[0]]);
    Vec3 mid = (m.positions[f[0]] + m.positions[f[1]] + m.positions[f[2]]) / 3.0;
    EXPECT_GT(n.dot(mid - c), 0.0);
  }
}

TEST(TetMeshIo, BadFilesGetMessagesThatSayWhat) {
  EXPECT_EQ(ReadVtu("hello").error().code, ErrorCode::kInvalidArgument);
  std::string v = WriteVtu(TwoTets());
  std::string hex = v;
  hex.replace(hex.find("          10\n"), 13, "          12\n");
  auto r = ReadVtu(hex);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("type 12"), std::string::npos) << r.error().message;
  std::string oob = v;
  oob.replace(oob.find("          0 1 ", oob.find("connectivity")), 14, "          0 9 ");
  r = ReadVtu(oob);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("point 9"), std::string::npos) << r.error().message;
}

}  // namespace
TEST(TetMeshIo, BlobRoundTripAndCorruptionIsDataLoss) {
  TetMesh m;
  m.positions = {{0.1, 0.2, 0.3}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  m.tets = {{0, 1, 2, 3}};
  m.surface = {{1, 2, 3}};
  std::string blob = EncodeMeshBlob(m);
  auto r = DecodeMeshBlob(blob);
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r->positions, m.positions);
  EXPECT_EQ(r->tets, m.tets);
  EXPECT_EQ(r->surface, m.surface);
  auto truncated = DecodeMeshBlob(blob.substr(0, blob.size() - 1));
  ASSERT_FALSE(truncated.ok());
  EXPECT_EQ(truncated.error().code, ErrorCode::kDataLoss);
  std::string bad = blob;
  bad[bad.size() - 4] = 9;  // a surface index beyond the vertex count
  auto bad_index = DecodeMeshBlob(bad);
  ASSERT_FALSE(bad_index.ok());
  EXPECT_EQ(bad_index.error().code, ErrorCode::kDataLoss);
  EXPECT_NE(bad_index.error().message.find("out of range"), std::string::npos);
}

}  // namespace rheo
