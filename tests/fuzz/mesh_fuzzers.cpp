// libFuzzer targets for the mesh readers (io/mesh_io.hpp). Built as one executable per
// reader, selected by FIBERFEM_FUZZ_TARGET: a reader either returns a valid mesh or throws
// MeshFileError naming the file and line; anything else (another exception, a crash, a
// sanitizer report, a hang) is a bug. With clang and -DFIBERFEM_FUZZ=ON they link against
// libFuzzer (scripts/fuzz.sh); otherwise replay_main.cpp runs the kept corpus
// (tests/fuzz/corpus/<target>/) through them as a regular test.

#include "io/mesh_io.hpp"

#include <cstddef>
#include <cstdint>
#include <sstream>
#include <string>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
#if FIBERFEM_FUZZ_TARGET == 1
    // Both gmsh readers: the linear one, and the one of either order (10-node tetrahedra
    // and the element-mesh checks behind them).
    try {
      std::istringstream in(text);
      (void)fiberfem::io::read_gmsh(in, "fuzz.msh");
    } catch (const fiberfem::io::MeshFileError&) {
    }
    std::istringstream in(text);
    (void)fiberfem::io::read_gmsh_any_order(in, "fuzz.msh");
#elif FIBERFEM_FUZZ_TARGET == 2
    std::istringstream in(text);
    (void)fiberfem::io::read_vtk(in, "fuzz.vtk");
#elif FIBERFEM_FUZZ_TARGET == 3
    // TetGen needs two files: the input is "<.node text>\n--- ele ---\n<.ele text>".
    const std::string cut = "\n--- ele ---\n";
    const size_t at = text.find(cut);
    std::istringstream node(text.substr(0, at));
    std::istringstream ele(at == std::string::npos ? std::string() : text.substr(at + cut.size()));
    (void)fiberfem::io::read_tetgen(node, "fuzz.node", ele, "fuzz.ele");
#else
#error "FIBERFEM_FUZZ_TARGET must be 1 (gmsh), 2 (vtk) or 3 (tetgen)"
#endif
  } catch (const fiberfem::io::MeshFileError&) {
    // The expected refusal.
  }
  return 0;
}
