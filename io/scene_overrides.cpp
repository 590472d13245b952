// --set overrides (docs/options.md) and the scene text as a YAML tree.

#include "io/scene_internal.hpp"

namespace fiberfem::io::detail {

YAML::Node load_document(const std::string& yaml_text, const std::string& origin, const std::string& kind) {
  try {
    return YAML::Load(yaml_text);
  } catch (const YAML::ParserException& e) {
    throw SceneError(origin + ":" + std::to_string(e.mark.line + 1) + ": not valid " + kind + ": " + e.msg);
  }
}

// Applies "a.b[2].c=value" to the tree (YAML::Node handles are references into it).
void apply_override(YAML::Node root, const std::string& assignment) {
  const size_t eq = assignment.find('=');
  if (eq == std::string::npos || eq == 0)
    throw SceneError("--set " + assignment + ": expected key.path=value");
  const std::string path = assignment.substr(0, eq);
  YAML::Node value;
  try {
    value = YAML::Load(assignment.substr(eq + 1));
  } catch (const YAML::Exception& e) {
    throw SceneError("--set " + assignment + ": the value is not valid YAML: " + e.msg);
  }
  // Split into keys and [index] parts.
  std::vector<std::pair<std::string, long>> parts;  // key or (empty, index)
  size_t i = 0;
  while (i < path.size()) {
    if (path[i] == '.') {
      ++i;
      continue;
    }
    if (path[i] == '[') {
      const size_t close = path.find(']', i);
      if (close == std::string::npos) throw SceneError("--set " + assignment + ": unclosed [");
      try {
        parts.emplace_back("", std::stol(path.substr(i + 1, close - i - 1)));
      } catch (const std::exception&) {
        throw SceneError("--set " + assignment + ": bad list index");
      }
      i = close + 1;
      continue;
    }
    const size_t end = path.find_first_of(".[", i);
    parts.emplace_back(path.substr(i, end == std::string::npos ? std::string::npos : end - i), -1);
    i = end == std::string::npos ? path.size() : end;
  }
  if (parts.empty()) throw SceneError("--set " + assignment + ": empty key path");
  YAML::Node node = root;
  for (size_t k = 0; k < parts.size(); ++k) {
    const bool last = k + 1 == parts.size();
    if (parts[k].first.empty()) {
      const long idx = parts[k].second;
      if (!node.IsSequence() || idx < 0 || idx >= static_cast<long>(node.size()))
        throw SceneError("--set " + assignment + ": no list element [" + std::to_string(idx) + "] there");
      if (last) {
        node[static_cast<size_t>(idx)] = value;
        return;
      }
      node.reset(node[static_cast<size_t>(idx)]);
    } else {
      if (!node.IsMap() && !node.IsNull())
        throw SceneError("--set " + assignment + ": '" + parts[k].first + "' is not under a mapping");
      if (last) {
        node[parts[k].first] = value;
        return;
      }
      YAML::Node child = node[parts[k].first];
      if (!child.IsDefined() || child.IsNull()) {  // a missing mapping on the way is created
        node[parts[k].first] = YAML::Node(YAML::NodeType::Map);
        child = node[parts[k].first];
      }
      node.reset(child);
    }
  }
}


}  // namespace fiberfem::io::detail
