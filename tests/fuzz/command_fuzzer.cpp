// libFuzzer target for the command decoder: the bytes are one fiberfem::Command sample
// (idl/control.idl), its string fields run_id, command_id, client_id, kind and args
// separated by NUL bytes (a missing field is a null pointer, as a sample without it
// would carry). The sample goes through what the service does with one it receives:
// decode_command (idl/command_sample.hpp), RunControl::apply on a small running beam
// (service/run_control.hpp), then a step. A refusal must name what is wrong; anything
// else (an escaped exception, a crash, a sanitizer report, a hang) is a finding.

#include "io/scene.hpp"
#include "idl/command_sample.hpp"
#include "service/run_control.hpp"

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

namespace {

const char* kBeam = R"(
name: fuzz-beam
mesh: {generator: box, size: [0.1, 0.02, 0.02], cells: [3, 1, 1]}
regions:
  - name: tissue
    select: all
    material: {E_L: 60.0e3, E_T: 20.0e3, nu_LT: 0.25, nu_T: 0.45, G_L: 8.0e3, density: 1000.0}
    damping: {mass: 40.0, stiffness: 0.0}
fibers: {uniform: [1, 0, 0]}
fixed:
  - plane: {axis: x, value: 0.0}
loads: {gravity: [0, 0, -9.81]}
contraction: {peak_tension: 1000, heart_rate: 60}
solver: {dt: 0.01}
)";

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const fiberfem::io::Scene scene = fiberfem::io::parse_scene(kBeam, "fuzz-beam", "/nonexistent-fiberfem-fuzz");
  std::vector<std::string> fields;
  std::string cur;
  for (size_t i = 0; i < size; ++i) {
    if (data[i] == 0 && fields.size() < 4) {
      fields.push_back(cur);
      cur.clear();
    } else {
      cur.push_back(static_cast<char>(data[i]));
    }
  }
  fields.push_back(cur);
  fiberfem_Command sample{};
  char** slots[] = {&sample.run_id, &sample.command_id, &sample.client_id, &sample.kind, &sample.args};
  for (size_t k = 0; k < fields.size(); ++k) *slots[k] = fields[k].data();  // text up to its first NUL, as DDS delivers it

  fiberfem::dds::DecodedCommand d;
  try {
    d = fiberfem::dds::decode_command(sample);
  } catch (const fiberfem::dds::CommandSampleError& e) {
    if (std::string(e.what()).find("command field '") == std::string::npos) {
      std::fprintf(stderr, "refusal without the field: %s\n", e.what());
      std::abort();
    }
    return 0;
  }
  fiberfem::service::RunControl rc(scene);
  const fiberfem::service::CommandResult r = rc.apply(d.kind, d.args);
  if (!r.accepted && r.reason.empty()) {
    std::fprintf(stderr, "refused without a reason\n");
    std::abort();
  }
  rc.before_step();
  if (rc.take_step_permission()) (void)rc.simulator().step();  // a numerical failure is a report, not a throw
  return 0;
}
