// `fiberfem render RUN.h5`: an archive read frame by frame (docs/rendering.md).

#include "service/app/render_feed.hpp"

#include "clients/render/field.hpp"
#include "io/scene.hpp"
#include "service/archive/archive.hpp"

#include <algorithm>
#include <iostream>
#include <memory>
#include <optional>
#include <stdexcept>

namespace fiberfem::app {

// An archive: the mesh, fibers and regions from its header; the contraction (for the
// activation's normalisation and the beat count) from its scene text when that parses.
Feed archive_feed(const RenderArgs& a) {
  auto reader = std::make_shared<archive::ArchiveReader>(a.scene_file);
  const archive::ArchiveHeader& h = reader->header();
  Feed f;
  f.name = h.scene_name;
  f.origin = "archive " + a.scene_file;
  f.mesh.emplace(h.rest_positions, h.tets, h.regions);
  f.fibers = h.fibers;
  try {
    f.contraction = io::parse_scene(h.scene_yaml, "archive:" + a.scene_file, h.scene_base_dir).model.contraction;
  } catch (const std::exception& e) {
    std::cerr << "fiberfem render: the archived scene does not parse here (" << e.what()
              << "); activation is shown relative to each frame's largest\n";
  }
  f.total = reader->frames();
  if (f.total == 0) throw std::runtime_error(a.scene_file + ": the archive has no frames");
  const std::vector<double> times = reader->times();
  f.frame_dt_s = f.total > 1 ? (times.back() - times.front()) / static_cast<double>(f.total - 1) : h.dt_s;
  // Activation when the scene contracts, or (its text not parsing here) when the last frame
  // has any (an archive stores zeros without a contraction).
  const std::vector<double> last_act = reader->frame(f.total - 1).activation_pa;
  f.has_activation = f.contraction.enabled() || std::any_of(last_act.begin(), last_act.end(), [](double v) { return v > 0; });
  // The circulation of the frame next() read last (an archive of a run with one).
  auto circulation = std::make_shared<std::optional<core::circulation::Snapshot>>();
  if (!h.circulation_columns.empty())
    f.circulation = [circulation] {
      return *circulation ? std::vector<core::circulation::Snapshot>{**circulation} : std::vector<core::circulation::Snapshot>{};
    };
  long i = 0;
  const long stop = a.until > 0 ? static_cast<long>(std::upper_bound(times.begin(), times.end(), a.until + 1e-9) - times.begin()) : f.total;
  f.next = [reader, circulation, contraction = f.contraction, regions = f.mesh->regions(), i, stop](
               core::Positions& x, std::vector<double>& act, double& t, long& step) mutable {
    if (i >= stop) return false;
    const archive::Frame fr = reader->frame(i++);
    *circulation = fr.circulation;
    x = fr.positions;
    t = fr.time_s, step = fr.step;
    if (contraction.enabled()) {
      act = render::activation_from_tension(contraction, regions, fr.activation_pa);
    } else {
      act = fr.activation_pa;
      const double peak = act.empty() ? 0.0 : *std::max_element(act.begin(), act.end());
      for (double& v : act) v = peak > 0 ? v / peak : 0.0;
    }
    return true;
  };
  return f;
}


}  // namespace fiberfem::app
