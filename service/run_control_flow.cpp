// Commands that drive the run: pause, resume, step, shutdown, reset, checkpoint, restore
// (docs/commands.md). Each checks its arguments before it changes anything.

#include "service/run_control.hpp"

#include "service/command_args.hpp"

namespace fiberfem::service {

using detail::Args;
using detail::join;
using detail::Reject;

CommandResult RunControl::on_pause(const Args&) {
  paused_ = true;
  ordered_steps_ = 0;
  return {true, "paused"};
}

CommandResult RunControl::on_resume(const Args&) {
  paused_ = false;
  ordered_steps_ = 0;
  return {true, "running"};
}

CommandResult RunControl::on_step(const Args& a) {
  const int n = a.has("count") ? a.integer("count", 1, 1000000) : 1;
  paused_ = true;
  ordered_steps_ += n;
  return {true, std::to_string(n) + " steps ordered, then paused"};
}

CommandResult RunControl::on_shutdown(const Args&) {
  shutdown_ = true;
  return {true, "shutting down"};
}

CommandResult RunControl::on_reset(const Args& a) {
  const bool parameters = a.has("parameters") && a.boolean("parameters");
  if (parameters) {
    auto fresh = make_engine(scene_);
    engine_ = std::move(fresh);
    scene_doc_ = scene_.yaml_text;
    params_ = scene_.parameters;
    base_loads_ = scene_.model.loads;
    forces_.clear();
    ++topology_version_;
    return {true, "reset to rest with the scene's parameters"};
  }
  engine_->reset();
  return {true, "reset to rest"};
}

CommandResult RunControl::on_checkpoint(const Args& a) {
  const std::string name = a.has("name") ? a.text("name") : "default";
  if (name.empty()) throw Reject("'name' must not be empty");
  checkpoints_[name] = Saved{engine_->checkpoint(), parameter_state_json()};
  return {true, "checkpoint '" + name + "' at t = " + std::to_string(engine_->time_s()) + " s"};
}

CommandResult RunControl::on_restore(const Args& a) {
  const std::string name = a.has("name") ? a.text("name") : "default";
  const auto it = checkpoints_.find(name);
  if (it == checkpoints_.end()) {
    std::vector<std::string> saved;
    for (const auto& kv : checkpoints_) saved.push_back(kv.first);
    throw Reject("no checkpoint '" + name + "'" + (saved.empty() ? " (none saved)" : " (saved: " + join(saved) + ")"));
  }
  // Parameters changed since: rebuild for the saved ones first (the state only fits them).
  if (it->second.parameters != parameter_state_json()) restore_parameter_state(it->second.parameters);
  engine_->restore(it->second.state);
  return {true, "restored '" + name + "' (t = " + std::to_string(engine_->time_s()) + " s)"};
}

}  // namespace fiberfem::service
