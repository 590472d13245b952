// `fiberfem archive info|recover|export-meshio|export-circulation RUN.h5`: look into a run
// archive, make a crashed one openable by ordinary readers, export it for meshio or its
// circulation as CSV (docs/archive.md).

#include "core/circulation/circulation.hpp"
#include "service/archive/archive.hpp"
#include "service/app/commands.hpp"

#include <CLI/CLI.hpp>

#include <chrono>
#include <cstdio>
#include <iostream>
#include <memory>
#include <thread>

namespace fiberfem::app {
namespace {

struct ArchiveArgs {
  std::string path, out;
  bool follow = false;
  double follow_seconds = 0;
};

void print_info(const archive::ArchiveReader& r, std::ostream& out) {
  const archive::ArchiveHeader& h = r.header();
  char line[512];
  std::snprintf(line, sizeof line, "archive: %s: format %s version %d, fiberfem %s (%s), created %s\n", r.path().c_str(),
                archive::kFormatName, h.format_version, h.software_version.c_str(), h.git_commit.substr(0, 12).c_str(),
                h.created_utc.c_str());
  out << line;
  out << "scene: " << h.scene_name << " (sha256 " << h.scene_sha256.substr(0, 16) << "...), source " << h.source << "\n";
  std::snprintf(line, sizeof line, "mesh: %ld nodes, %zu tets, %zu regions; dt %.6g s, every %d steps%s\n",
                static_cast<long>(h.rest_positions.cols()), h.tets.size(), h.density_kg_m3.size(), h.dt_s, h.every_steps,
                h.has_velocities ? ", with velocities" : "");
  out << line;
  const std::vector<double> t = r.times();
  const std::vector<long> s = r.steps();
  if (t.empty()) {
    out << "frames: 0\n";
  } else {
    std::snprintf(line, sizeof line, "frames: %ld, t = %.6g to %.6g s, steps %ld to %ld\n", r.frames(), t.front(), t.back(), s.front(),
                  s.back());
    out << line;
  }
  if (!h.circulation_columns.empty() && r.frames() > 0) {  // the last frame's circulation and beat
    namespace cc = core::circulation;
    const cc::Snapshot c = *r.frame(r.frames() - 1).circulation;
    std::snprintf(line, sizeof line,
                  "circulation: per frame (%zu columns); last frame: LV %.2f mmHg %.3f mL, RV %.2f mmHg %.3f mL, aortic %.2f mmHg\n",
                  h.circulation_columns.size(), c.chamber_pressure_pa[cc::lv] / cc::kPaPerMmHg, c.chamber_volume_m3[cc::lv] / cc::kM3PerMl,
                  c.chamber_pressure_pa[cc::rv] / cc::kPaPerMmHg, c.chamber_volume_m3[cc::rv] / cc::kM3PerMl,
                  c.compartment_pressure_pa[cc::ar_sys] / cc::kPaPerMmHg);
    out << line;
    if (c.last_beat.index >= 0) out << "circulation: beat " << c.last_beat.index << ": " << cc::describe(c.last_beat) << "\n";
  }
  const auto cps = r.checkpoints();
  out << "checkpoints: " << cps.size();
  for (const auto& c : cps) {
    std::snprintf(line, sizeof line, " %.6g s (step %ld);", c.time_s, c.step);
    out << line;
  }
  out << "\n";
  const auto cmds = r.commands();
  out << "commands: " << cmds.size() << "\n";
  for (const auto& c : cmds)
    out << "  step " << c.step << " t=" << c.time_s << " " << c.kind << " id=" << c.id << " " << (c.accepted ? "accepted" : "rejected: " + c.reason)
        << "\n";
}

}  // namespace

void add_archive_command(CLI::App& app, int& exit_code) {
  auto* cmd = app.add_subcommand("archive", "Inspect, recover or export a run archive (docs/archive.md)");
  cmd->require_subcommand(1);
  auto a = std::make_shared<ArchiveArgs>();

  auto* info = cmd->add_subcommand("info", "Frames, times, checkpoints and commands of RUN.h5 (also while it is written)");
  info->add_option("archive", a->path, "The run archive (.h5)")->required();
  info->add_flag("--follow", a->follow, "Keep printing the frame count as a live writer adds frames (SWMR)");
  info->add_option("--follow-seconds", a->follow_seconds, "With --follow: stop after this long, s (0: until the writer stops growing for 5 s)")
      ->check(CLI::NonNegativeNumber);
  info->callback([a, &exit_code] {
    try {
      archive::ArchiveReader r(a->path, /*follow=*/true);
      print_info(r, std::cout);
      if (a->follow) {
        const auto t0 = std::chrono::steady_clock::now();
        auto last_change = t0;
        long last = r.frames();
        for (;;) {
          std::this_thread::sleep_for(std::chrono::milliseconds(200));
          const long n = r.refresh();
          const auto now = std::chrono::steady_clock::now();
          if (n != last) {
            std::cout << "frames: " << n << "\n" << std::flush;
            last = n;
            last_change = now;
          }
          const double since_start = std::chrono::duration<double>(now - t0).count();
          const double idle = std::chrono::duration<double>(now - last_change).count();
          if ((a->follow_seconds > 0 && since_start >= a->follow_seconds) || (a->follow_seconds == 0 && idle >= 5)) break;
        }
      }
      exit_code = 0;
    } catch (const std::exception& e) {
      std::cerr << "fiberfem archive info: " << e.what() << "\n";
      exit_code = 1;
    }
  });

  auto* recover = cmd->add_subcommand("recover", "Make RUN.h5 of a crashed writer openable without SWMR; regenerate RUN.xdmf");
  recover->add_option("archive", a->path, "The run archive (.h5)")->required();
  recover->callback([a, &exit_code] {
    try {
      const long frames = archive::recover(a->path);
      std::cout << "recover: " << a->path << ": " << frames << " intact frames; sidecar rewritten\n";
      exit_code = 0;
    } catch (const std::exception& e) {
      std::cerr << "fiberfem archive recover: " << e.what() << "\n";
      exit_code = 1;
    }
  });

  auto* xdmf = cmd->add_subcommand("xdmf", "Rewrite RUN.xdmf from RUN.h5 (also while a writer adds frames)");
  xdmf->add_option("archive", a->path, "The run archive (.h5)")->required();
  xdmf->callback([a, &exit_code] {
    try {
      archive::write_xdmf(a->path);
      std::cout << "xdmf: sidecar of " << a->path << " rewritten\n";
      exit_code = 0;
    } catch (const std::exception& e) {
      std::cerr << "fiberfem archive xdmf: " << e.what() << "\n";
      exit_code = 1;
    }
  });

  auto* circ = cmd->add_subcommand("export-circulation",
                                   "Write the circulation of every frame as CSV (step and the archive's columns, SI units)");
  circ->add_option("archive", a->path, "The run archive (.h5) of a run with a circulation")->required();
  circ->add_option("out", a->out, "The CSV file to write")->required();
  circ->callback([a, &exit_code] {
    try {
      const long frames = archive::export_circulation_csv(a->path, a->out);
      std::cout << "export-circulation: " << a->out << ": " << frames << " frames\n";
      exit_code = 0;
    } catch (const std::exception& e) {
      std::cerr << "fiberfem archive export-circulation: " << e.what() << "\n";
      exit_code = 1;
    }
  });

  auto* exp = cmd->add_subcommand("export-meshio", "Write OUT.xdmf + OUT.h5, one dataset per step (meshio's time-series layout)");
  exp->add_option("archive", a->path, "The run archive (.h5)")->required();
  exp->add_option("out", a->out, "The XDMF file to write (its data go to OUT.h5 beside it)")->required();
  exp->callback([a, &exit_code] {
    try {
      archive::export_meshio(a->path, a->out);
      std::cout << "export-meshio: " << a->out << "\n";
      exit_code = 0;
    } catch (const std::exception& e) {
      std::cerr << "fiberfem archive export-meshio: " << e.what() << "\n";
      exit_code = 1;
    }
  });
}

}  // namespace fiberfem::app
