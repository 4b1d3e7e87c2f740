// Tetrahedral mesh file formats as strings: the callers own the files.
#pragma once

#include <string>
#include <string_view>

#include "common/geometry.h"
#include "common/status.h"

namespace rheo {

/// VTK XML UnstructuredGrid (.vtu), ASCII, tetrahedra only (VTK cell type 10). ParaView and
/// meshio read it.
std::string WriteVtu(const TetMesh& mesh);

/// Reads an ASCII .vtu holding tetrahedra (other cell types are refused with a message). The
/// boundary surface is rebuilt from the faces used by exactly one tetrahedron, and tetrahedra
/// with negative orientation are flipped.
Result<TetMesh> ReadVtu(std::string_view text);

/// The compact binary blob the object store keeps (little-endian: a "RHOM" magic, a version,
/// the three counts, then doubles for positions and int32s for tetrahedra and surface).
std::string EncodeMeshBlob(const TetMesh& mesh);
/// DATA_LOSS for an unknown header, a wrong length or an index out of range.
Result<TetMesh> DecodeMeshBlob(std::string_view blob);

/// Rebuilds mesh.surface from the tetrahedra: faces used once, oriented outward.
void ComputeBoundary(TetMesh& mesh);

}  // namespace rheo
