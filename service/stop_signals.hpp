#pragma once
/// @file SIGINT and SIGTERM turned into a flag that a loop polls at its step boundary
/// (batch runs, the service, replay, the renderer, the command-line client), restored to
/// their previous handlers when the guard goes.

#include <csignal>

namespace fiberfem::service {

namespace detail {
inline volatile std::sig_atomic_t g_stop_signal = 0;
extern "C" inline void fiberfem_on_stop_signal(int sig) { g_stop_signal = sig; }
}  // namespace detail

/// While it lives, SIGINT and SIGTERM (or SIGINT alone) set a flag instead of ending the process.
class StopSignals {
 public:
  explicit StopSignals(bool term_too = true) : term_too_(term_too) {
    detail::g_stop_signal = 0;
    old_int_ = std::signal(SIGINT, detail::fiberfem_on_stop_signal);
    if (term_too_) old_term_ = std::signal(SIGTERM, detail::fiberfem_on_stop_signal);
  }
  ~StopSignals() {
    std::signal(SIGINT, old_int_);
    if (term_too_) std::signal(SIGTERM, old_term_);
  }
  StopSignals(const StopSignals&) = delete;
  StopSignals& operator=(const StopSignals&) = delete;
  /// The signal caught (SIGINT or SIGTERM), 0 while none.
  int caught() const { return detail::g_stop_signal; }
  /// "SIGINT" or "SIGTERM".
  const char* name() const { return caught() == SIGINT ? "SIGINT" : "SIGTERM"; }

 private:
  bool term_too_;
  void (*old_int_)(int) = SIG_DFL;
  void (*old_term_)(int) = SIG_DFL;
};

}  // namespace fiberfem::service
