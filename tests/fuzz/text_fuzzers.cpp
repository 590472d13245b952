// libFuzzer targets for the text readers that take a whole file: the scene reader
// (io/scene.hpp, YAML), the fiber and stroke file readers (io/fiber_file.hpp) and the
// cycle script reader (clients/ctl/cycle.hpp). One executable per reader, selected by
// FIBERFEM_FUZZ_TARGET. A reader either returns or throws its own error type, whose
// message names the file (docs/bad-input.md); any other exception escapes and aborts, which
// libFuzzer reports as a crash, as it does sanitizer reports and hangs.

#include <cstddef>
#include <cstdint>
#include <sstream>
#include <string>

#if FIBERFEM_FUZZ_TARGET == 1
#include "io/scene.hpp"
#elif FIBERFEM_FUZZ_TARGET == 2
#include "io/fiber_file.hpp"
#elif FIBERFEM_FUZZ_TARGET == 3
#include "clients/ctl/cycle.hpp"
#else
#error "FIBERFEM_FUZZ_TARGET must be 1 (scene), 2 (fiber) or 3 (cycle)"
#endif

namespace {
[[noreturn]] void unexpected_message(const std::string& what) {
  std::fprintf(stderr, "error message without its origin: %s\n", what.c_str());
  std::abort();
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
#if FIBERFEM_FUZZ_TARGET == 1
  try {
    // Relative files (meshes, fibers, strokes) resolve in a directory that does not exist:
    // the scene text is what is fuzzed, not whatever files the machine holds.
    (void)fiberfem::io::parse_scene(text, "fuzz.yaml", "/nonexistent-fiberfem-fuzz");
  } catch (const fiberfem::io::SceneError& e) {
    if (std::string(e.what()).find("fuzz.yaml") == std::string::npos) unexpected_message(e.what());
  }
#elif FIBERFEM_FUZZ_TARGET == 2
  // The first byte picks the reader: fiber vectors or stroke polylines.
  const bool strokes = size > 0 && (data[0] & 1);
  std::istringstream in(size > 0 ? text.substr(1) : text);
  try {
    if (strokes)
      (void)fiberfem::io::read_polylines(in, "fuzz.txt");
    else
      (void)fiberfem::io::read_fiber_vectors(in, "fuzz.txt");
  } catch (const fiberfem::io::FiberFileError& e) {
    if (std::string(e.what()).rfind("fuzz.txt:", 0) != 0) unexpected_message(e.what());
  }
#elif FIBERFEM_FUZZ_TARGET == 3
  try {
    (void)fiberfem::clients::parse_cycle(text, "fuzz.yaml");
  } catch (const fiberfem::clients::CycleError& e) {
    if (std::string(e.what()).rfind("fuzz.yaml", 0) != 0) unexpected_message(e.what());
  }
#endif
  return 0;
}
