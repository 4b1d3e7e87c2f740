#include "common/tet_mesh_io.h"

#include <algorithm>
#include <charconv>
#include <cstdio>
#include <cstring>
#include <map>
#include <sstream>

namespace rheo {
namespace {

// a + b + c, appended in place (GCC 12's -Wrestrict misfires on "literal" + std::string&&).
std::string Concat(std::string_view a, std::string_view b, std::string_view c = {}) {
  std::string out;
  out.reserve(a.size() + b.size() + c.size());
  out.append(a).append(b).append(c);
  return out;
}

// Finds the text of the <DataArray ... Name="name" ...> element inside `section`.
std::string_view FindArray(std::string_view doc, std::string_view section, std::string_view name) {
  size_t s = doc.find(Concat("<", section));
  if (s == std::string_view::npos) return {};
  size_t e = doc.find(Concat("</", section), s);
  if (e == std::string_view::npos) return {};
  std::string_view body = doc.substr(s, e - s);
  size_t pos = 0;
  while ((pos = body.find("<DataArray", pos)) != std::string_view::npos) {
    size_t tag_end = body.find('>', pos);
    if (tag_end == std::string_view::npos) return {};
    std::string_view tag = body.substr(pos, tag_end - pos);
    bool named = name.empty() || tag.find(Concat("Name=\"", name, "\"")) != std::string_view::npos;
    size_t close = body.find("</DataArray>", tag_end);
    if (close == std::string_view::npos) return {};
    if (named) {
      if (tag.find("format=\"binary\"") != std::string_view::npos ||
          tag.find("format=\"appended\"") != std::string_view::npos)
        return "binary";
      return body.substr(tag_end + 1, close - tag_end - 1);
    }
    pos = close;
  }
  return {};
}

template <typename T>
bool ParseNumbers(std::string_view text, std::vector<T>& out) {
  const char* p = text.data();
  const char* end = p + text.size();
  while (p < end) {
    while (p < end && (*p == ' ' || *p == '\n' || *p == '\r' || *p == '\t')) ++p;
    if (p >= end) break;
    T v{};
    auto [next, ec] = std::from_chars(p, end, v);
    if (ec != std::errc()) return false;
    out.push_back(v);
    p = next;
  }
  return true;
}

double Orientation(const TetMesh& m, const std::array<int32_t, 4>& t) {
  const Vec3& a = m.positions[t[0]];
  return (m.positions[t[1]] - a).dot((m.positions[t[2]] - a).cross(m.positions[t[3]] - a));
}

constexpr uint32_t kMeshMagic = 0x4d4f4852;  // "RHOM"
constexpr uint32_t kMeshVersion = 1;

template <typename T>
void Append(std::string& out, const T& v) {
  out.append(reinterpret_cast<const char*>(&v), sizeof(T));
}

template <typename T>
bool Take(std::string_view in, size_t& pos, T& v) {
  if (pos + sizeof(T) > in.size()) return false;
  std::memcpy(&v, in.data() + pos, sizeof(T));
  pos += sizeof(T);
  return true;
}

}  // namespace

std::string WriteVtu(const TetMesh& mesh) {
  std::ostringstream os;
  os.precision(17);
  os << "<?xml version=\"1.0\"?>\n"
     << "<VTKFile type=\"UnstructuredGrid\" version=\"0.1\" byte_order=\"LittleEndian\">\n"
     << "  <UnstructuredGrid>\n"
     << "    <Piece NumberOfPoints=\"" << mesh.positions.size() << "\" NumberOfCells=\""
     << mesh.tets.size() << "\">\n"
     << "      <Points>\n"
     << "        <DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">\n";
  for (const Vec3& p : mesh.positions)
    os << "          " << p.x() << ' ' << p.y() << ' ' << p.z() << '\n';
  os << "        </DataArray>\n      </Points>\n      <Cells>\n"
     << "        <DataArray type=\"Int32\" Name=\"connectivity\" format=\"ascii\">\n";
  for (const auto& t : mesh.tets)
    os << "          " << t[0] << ' ' << t[1] << ' ' << t[2] << ' ' << t[3] << '\n';
  os << "        </DataArray>\n"
     << "        <DataArray type=\"Int32\" Name=\"offsets\" format=\"ascii\">\n";
  for (size_t i = 0; i < mesh.tets.size(); ++i) os << "          " << 4 * (i + 1) << '\n';
  os << "        </DataArray>\n"
     << "        <DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">\n";
  for (size_t i = 0; i < mesh.tets.size(); ++i) os << "          10\n";
  os << "        </DataArray>\n      </Cells>\n    </Piece>\n  </UnstructuredGrid>\n</VTKFile>\n";
  return os.str();
}

Result<TetMesh> ReadVtu(std::string_view text) {
  if (text.find("UnstructuredGrid") == std::string_view::npos)
    return InvalidArgument("not a VTK UnstructuredGrid (.vtu) file");
  std::string_view pts = FindArray(text, "Points", "");
  std::string_view conn = FindArray(text, "Cells", "connectivity");
  std::string_view offs = FindArray(text, "Cells", "offsets");
  std::string_view types = FindArray(text, "Cells", "types");
  if (pts.empty() || conn.empty() || offs.empty() || types.empty())
    return InvalidArgument(".vtu file lacks Points or Cells (connectivity, offsets, types)");
  if (pts == "binary" || conn == "binary" || offs == "binary" || types == "binary")
    return InvalidArgument(".vtu file uses binary or appended data; only ASCII is read");
  std::vector<double> xyz;
  std::vector<int64_t> c, o, ty;
  if (!ParseNumbers(pts, xyz) || !ParseNumbers(conn, c) || !ParseNumbers(offs, o) ||
      !ParseNumbers(types, ty))
    return InvalidArgument(".vtu file has a malformed number in its data arrays");
  if (xyz.size() % 3 != 0) return InvalidArgument(".vtu Points count is not a multiple of 3");
  if (o.size() != ty.size()) return InvalidArgument(".vtu offsets and types differ in length");
  TetMesh mesh;
  const size_t n = xyz.size() / 3;
  mesh.positions.reserve(n);
  for (size_t i = 0; i < n; ++i)
    mesh.positions.emplace_back(xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]);
  int64_t prev = 0;
  for (size_t i = 0; i < o.size(); ++i) {
    if (ty[i] != 10)
      return InvalidArgument("cell " + std::to_string(i) + " has VTK type " +
                             std::to_string(ty[i]) + "; only tetrahedra (type 10) are supported");
    if (o[i] != prev + 4 || o[i] > static_cast<int64_t>(c.size()))
      return InvalidArgument("cell " + std::to_string(i) + " has a bad offset");
    std::array<int32_t, 4> t;
    for (int k = 0; k < 4; ++k) {
      int64_t v = c[prev + k];
      if (v < 0 || v >= static_cast<int64_t>(n))
        return InvalidArgument("cell " + std::to_string(i) + " refers to point " +
                               std::to_string(v) + " of " + std::to_string(n));
      t[k] = static_cast<int32_t>(v);
    }
    prev = o[i];
    if (Orientation(mesh, t) < 0) std::swap(t[2], t[3]);
    mesh.tets.push_back(t);
  }
  if (mesh.tets.empty()) return InvalidArgument(".vtu file holds no tetrahedra");
  ComputeBoundary(mesh);
  return mesh;
}

void ComputeBoundary(TetMesh& mesh) {
  // Faces of a positively oriented tet (a,b,c,d), outward: (b,c,d) (a,d,c) (a,b,d) (a,c,b).
  std::map<std::array<int32_t, 3>, std::pair<int, std::array<int32_t, 3>>> faces;
  for (const auto& t : mesh.tets) {
    const std::array<std::array<int32_t, 3>, 4> f = {
        {{t[1], t[2], t[3]}, {t[0], t[3], t[2]}, {t[0], t[1], t[3]}, {t[0], t[2], t[1]}}};
    for (const auto& face : f) {
      auto key = face;
      std::sort(key.begin(), key.end());
      auto [it, inserted] = faces.try_emplace(key, 0, face);
      ++it->second.first;
    }
  }
  mesh.surface.clear();
  for (const auto& [key, v] : faces)
    if (v.first == 1) mesh.surface.push_back(v.second);
}

std::string EncodeMeshBlob(const TetMesh& m) {
  std::string out;
  out.reserve(16 + m.positions.size() * 24 + m.tets.size() * 16 + m.surface.size() * 12);
  Append(out, kMeshMagic);
  Append(out, kMeshVersion);
  Append(out, static_cast<uint32_t>(m.positions.size()));
  Append(out, static_cast<uint32_t>(m.tets.size()));
  Append(out, static_cast<uint32_t>(m.surface.size()));
  for (const Vec3& p : m.positions) {
    Append(out, p.x());
    Append(out, p.y());
    Append(out, p.z());
  }
  for (const auto& t : m.tets)
    for (int32_t v : t) Append(out, v);
  for (const auto& f : m.surface)
    for (int32_t v : f) Append(out, v);
  return out;
}

Result<TetMesh> DecodeMeshBlob(std::string_view blob) {
  size_t pos = 0;
  uint32_t magic = 0, version = 0, nv = 0, nt = 0, nf = 0;
  if (!Take(blob, pos, magic) || magic != kMeshMagic || !Take(blob, pos, version) ||
      version != kMeshVersion || !Take(blob, pos, nv) || !Take(blob, pos, nt) ||
      !Take(blob, pos, nf))
    return DataLoss("mesh blob has an unknown header");
  const size_t need =
      static_cast<size_t>(nv) * 24 + static_cast<size_t>(nt) * 16 + static_cast<size_t>(nf) * 12;
  if (blob.size() - pos != need) return DataLoss("mesh blob is truncated or has trailing bytes");
  TetMesh m;
  m.positions.resize(nv);
  for (auto& p : m.positions) {
    double x = 0.0, y = 0.0, z = 0.0;
    Take(blob, pos, x);
    Take(blob, pos, y);
    Take(blob, pos, z);
    p = Vec3(x, y, z);
  }
  m.tets.resize(nt);
  for (auto& t : m.tets)
    for (auto& v : t) {
      Take(blob, pos, v);
      if (v < 0 || static_cast<uint32_t>(v) >= nv)
        return DataLoss("mesh blob has a vertex index out of range");
    }
  m.surface.resize(nf);
  for (auto& f : m.surface)
    for (auto& v : f) {
      Take(blob, pos, v);
      if (v < 0 || static_cast<uint32_t>(v) >= nv)
        return DataLoss("mesh blob has a vertex index out of range");
    }
  return m;
}

}  // namespace rheo
