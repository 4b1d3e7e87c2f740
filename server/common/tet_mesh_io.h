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

/// Rebuilds mesh.surface from the tetrahedra: faces used once, oriented outward.
void ComputeBoundary(TetMesh& mesh);

}  // namespace rheo
