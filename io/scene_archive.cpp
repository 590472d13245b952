// archive (docs/archive.md): where and how a run is recorded.

#include "io/scene_internal.hpp"

namespace fiberfem::io {

namespace detail {

ArchiveSettings read_archive(const Checks& checks, const YAML::Node& node) {
  const CheckedMap a(checks, node, "archive",
                     {"path", "flush_frames", "flush_seconds", "every", "velocities", "displacement", "checkpoint_every",
                      "compression"});
  ArchiveSettings archive;
  archive.enabled = true;
  if (!a.has("path")) checks.fail(node, "archive.path", "required: the .h5 file to record into");
  archive.path = a.text("path");
  if (archive.path.empty()) checks.fail(a["path"], "archive.path", "must not be empty");
  if (a.has("flush_frames")) archive.flush_frames = a.integer("flush_frames", 1, 100000);
  if (a.has("flush_seconds")) archive.flush_seconds = a.number("flush_seconds", 0, 3600);
  if (a.has("every")) archive.every_steps = a.integer("every", 1, 1000000);
  if (a.has("velocities")) archive.velocities = a.boolean("velocities");
  if (a.has("displacement")) archive.displacement = a.boolean("displacement");
  if (a.has("checkpoint_every")) archive.checkpoint_every_s = a.number("checkpoint_every", 0, 1e9);
  if (a.has("compression")) archive.compression = a.integer("compression", 0, 9);
  return archive;
}

}  // namespace detail

ArchiveSettings parse_archive_settings(const std::string& yaml_text, const std::string& origin) {
  return detail::read_archive(Checks(origin), detail::load_document(yaml_text, origin, "YAML or JSON"));
}

}  // namespace fiberfem::io
