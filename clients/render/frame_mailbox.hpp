#pragma once
/// @file The newest frame, handed from a producer (the simulation loop, a bus reader) to
/// the render thread: publishing never waits for the renderer, and a frame that arrives
/// before the previous one was taken replaces it (counted as dropped). This is how a live
/// renderer keeps up without slowing the simulation.

#include "core/types.hpp"

#include <mutex>
#include <optional>
#include <string>
#include <vector>

namespace fiberfem::render {

/// An owned copy of the per-frame data (FrameView borrows from it).
struct FrameData {
  core::Positions x;                ///< 3 x N, metres.
  std::vector<double> activation;   ///< Per element, 1 (may be empty).
  double time_s = 0;                ///< Simulated time, s.
  long sequence = 0;                ///< Producer's frame counter (step number).
  std::string caption;
};

/// A one-slot mailbox: publish() overwrites, take() empties. Thread-safe.
class FrameMailbox {
 public:
  /// Stores `frame`, replacing one not yet taken (then dropped() grows by one).
  void publish(FrameData frame);
  /// The newest frame, or nothing if none arrived since the last take().
  std::optional<FrameData> take();
  /// Frames replaced before anyone took them.
  long dropped() const;

 private:
  mutable std::mutex mutex_;
  std::optional<FrameData> slot_;
  long dropped_ = 0;
};

}  // namespace fiberfem::render
