#include "clients/render/frame_mailbox.hpp"

namespace fiberfem::render {

void FrameMailbox::publish(FrameData frame) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (slot_) ++dropped_;
  slot_ = std::move(frame);
}

std::optional<FrameData> FrameMailbox::take() {
  std::lock_guard<std::mutex> lock(mutex_);
  std::optional<FrameData> out = std::move(slot_);
  slot_.reset();
  return out;
}

long FrameMailbox::dropped() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return dropped_;
}

}  // namespace fiberfem::render
