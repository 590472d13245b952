// libFuzzer target for the archive reader (service/archive/archive.hpp) as replay and
// resume use it. The first byte picks how the rest becomes an HDF5 file:
//   even: the bytes are the file itself;
//   odd:  the bytes are patches (4-byte little-endian offset, 1 byte value, repeated)
//         applied to a small valid archive made at start-up (a beam recorded for a few
//         steps with a command and checkpoints), which reaches the reader's own checks
//         past HDF5's signatures and checksums.
// The file is written to a temporary path and read through everything replay reads (the
// header, every frame, the commands, the checkpoints) and what resume does (the last
// checkpoint restored into the beam's simulator). A refusal is a std::runtime_error,
// std::invalid_argument or std::out_of_range; anything else escaping (a JSON exception, a
// length error, an allocation failure), a crash, a sanitizer report or a hang is a finding.

#include "service/archive/archive.hpp"
#include "io/scene.hpp"

#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

namespace {

const char* kBeam = R"(
name: fuzz-beam
mesh: {generator: box, size: [0.1, 0.02, 0.02], cells: [2, 1, 1]}
regions:
  - name: tissue
    select: all
    material: {E_L: 60.0e3, E_T: 20.0e3, nu_LT: 0.25, nu_T: 0.45, G_L: 8.0e3, density: 1000.0}
fibers: {uniform: [1, 0, 0]}
fixed:
  - plane: {axis: x, value: 0.0}
loads: {gravity: [0, 0, -9.81]}
contraction: {peak_tension: 1000, heart_rate: 60}
solver: {dt: 0.01}
)";

std::string temp_dir() {
  const char* shm = "/dev/shm";
  const std::string base = std::filesystem::is_directory(shm) ? shm : std::filesystem::temp_directory_path().string();
  const std::string dir = base + "/fiberfem-fuzz-archive-" + std::to_string(::getpid());
  std::filesystem::create_directories(dir);
  return dir;
}

struct Template {
  fiberfem::io::Scene scene = fiberfem::io::parse_scene(kBeam, "fuzz-beam", "/nonexistent-fiberfem-fuzz");
  std::string dir = temp_dir();
  std::string bytes;
  Template() {
    const std::string path = dir + "/template.h5";
    {
      fiberfem::core::Simulator sim(scene.model, scene.settings);
      fiberfem::archive::ArchiveOptions o;
      o.path = path;
      o.checkpoint_every_s = 0.02;
      fiberfem::service::RealTimeEngine engine(sim);
      fiberfem::archive::ArchiveWriter w(o, scene, engine, "fuzz");
      for (int i = 0; i < 4; ++i) {
        const auto r = sim.step();
        w.record_frame(engine, r, {});
        if (i == 1) w.record_command({sim.step_count(), sim.time_s(), "c1", "pause", "{}", true, ""});
      }
      w.checkpoint(engine, "{}");
      w.close();
    }
    std::ifstream in(path, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
};

void read_like_replay_and_resume(const std::string& path, const fiberfem::io::Scene& scene) {
  const fiberfem::archive::ArchiveReader r(path);
  (void)r.header();
  for (long i = 0; i < r.frames(); ++i) (void)r.frame(i);
  (void)r.times();
  (void)r.steps();
  (void)r.commands();
  const size_t k = r.checkpoint_at_or_before(HUGE_VAL);
  std::string parameters;
  const fiberfem::core::SimulatorCheckpoint c = r.read_checkpoint(k, &parameters);
  fiberfem::core::Simulator sim(scene.model, scene.settings);
  sim.restore(c);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const Template t;
  if (size == 0) return 0;
  std::string file;
  if ((data[0] & 1) == 0) {
    file.assign(reinterpret_cast<const char*>(data + 1), size - 1);
  } else {
    file = t.bytes;
    for (size_t i = 1; i + 5 <= size; i += 5) {
      const uint32_t at = static_cast<uint32_t>(data[i]) | static_cast<uint32_t>(data[i + 1]) << 8 |
                          static_cast<uint32_t>(data[i + 2]) << 16 | static_cast<uint32_t>(data[i + 3]) << 24;
      file[at % file.size()] = static_cast<char>(data[i + 4]);
    }
  }
  const std::string path = t.dir + "/input.h5";
  {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(file.data(), static_cast<std::streamsize>(file.size()));
  }
  try {
    read_like_replay_and_resume(path, t.scene);
  } catch (const std::runtime_error&) {
  } catch (const std::invalid_argument&) {
  } catch (const std::out_of_range&) {
  }
  return 0;
}
