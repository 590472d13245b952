// Files written by another tool: meshio (PyPI, installed into .venv by scripts/setup.sh)
// writes the same two tetrahedra as gmsh 2.2, gmsh 4.1 (no $Entities: tags as entity tags)
// and VTK 5.1 (OFFSETS/CONNECTIVITY cells, FIELD cell data) at test time; each is read back
// and compared with the points, cells and tags given to meshio.

#include "io/mesh_io.hpp"
#include "test_support.hpp"

#include <cstdlib>
#include <fstream>

namespace fio = fiberfem::io;
namespace core = fiberfem::core;

namespace {

const char* kScript = R"(import sys, numpy as np, meshio
out = sys.argv[1]
points = np.array([[0, 0, -1], [1, 0, 0], [0, 1, 0], [-1, -1, 0], [0, 0, 1]], dtype=float)
cells = [("tetra", np.array([[0, 1, 2, 3], [4, 3, 2, 1]]))]
tags = [np.array([4, 6])]
m = meshio.Mesh(points, cells, cell_data={"gmsh:physical": tags, "gmsh:geometrical": tags})
meshio.write(out + "/m22.msh", m, file_format="gmsh22", binary=False)
# MSH 4.1 from meshio: one block per cell type, its entity tag the block's tag.
m4 = meshio.Mesh(points, cells, cell_data={"gmsh:physical": [np.array([5, 5])], "gmsh:geometrical": [np.array([5, 5])]})
meshio.write(out + "/m41.msh", m4, file_format="gmsh", binary=False)
v = meshio.Mesh(points, cells, cell_data={"region": [np.array([4, 6], dtype=np.int32)]})
meshio.write(out + "/m.vtk", v, file_format="vtk", binary=False)
)";

}  // namespace

TEST(MeshioInterop, FilesWrittenByMeshioReadBack) {
  const std::string dir = ::testing::TempDir() + "/fiberfem_meshio";
  ASSERT_EQ(std::system(("mkdir -p " + dir).c_str()), 0);
  {
    std::ofstream f(dir + "/write.py");
    f << kScript;
  }
  const std::string cmd = std::string(FIBERFEM_PYTHON) + " " + dir + "/write.py " + dir;
  ASSERT_EQ(std::system(cmd.c_str()), 0) << "meshio not available: run scripts/setup.sh (" << cmd << ")";
  core::Positions X(3, 5);
  X << 0, 1, 0, -1, 0, 0, 0, 1, -1, 0, -1, 0, 0, 0, 1;
  for (const char* name : {"m22.msh", "m41.msh", "m.vtk"}) {
    SCOPED_TRACE(name);
    const core::TetMesh m = fio::read_mesh(dir + "/" + name);
    ASSERT_EQ(m.num_elements(), 2);
    EXPECT_EQ(m.rest_positions(), X);
    // Element 0 is given with positive volume and kept; the tags come through.
    EXPECT_EQ(m.tets()[0], (core::Tet{0, 1, 2, 3}));
    EXPECT_EQ(m.tets()[1], (core::Tet{4, 3, 2, 1}));
    EXPECT_EQ(m.regions(), std::string(name) == "m41.msh" ? (std::vector<int>{5, 5}) : (std::vector<int>{4, 6}));
  }
}
