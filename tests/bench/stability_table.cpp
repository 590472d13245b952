// bench_accuracy --stability: the stability map's table (tests/stability_map.hpp; the
// same cases tests/core/stability_map_test.cpp checks), written as Markdown.

#include "stability_map.hpp"

#include <cstdio>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>

namespace {
std::string g(double v, const char* f = "%.2g") {
  if (std::isnan(v)) return "";
  char b[64];
  std::snprintf(b, sizeof b, f, v);
  return b;
}

// The note column: what went wrong, then the case's own note, joined by "; ".
std::string note(const fiberfem::stability::Result& r) {
  std::string s = r.finite ? "" : "non-finite state";
  const auto add = [&s](const std::string& part) {
    if (!part.empty()) s += (s.empty() ? "" : "; ") + part;
  };
  if (r.failed_steps) add(std::to_string(r.failed_steps) + " failed steps");
  add(r.note);
  return s;
}
}  // namespace

int stability_main(const std::string& out_md, int /*threads*/) {
  namespace st = fiberfem::stability;
  std::ostringstream o;
  o << "| extreme | value | stable | steps (recovered) | max (K+E) / bound, loaded | max (K+E) / E_release | "
       "static reference | tip error vs reference | transient tip error vs dt 1/960 | rest error after release | note |\n"
       "|---|---|---|---:|---:|---:|---|---:|---:|---:|---|\n";
  for (const st::Case& c : st::cases()) {
    st::Result r = st::run_case(c);
    st::add_transient_error(c, r);
    o << "| " << c.group << " | " << c.value << " | " << (r.stable(c) ? "yes" : "**no**") << " | " << r.steps << " ("
      << r.recovered_steps << ") | " << g(r.energy_ratio, "%.3f") << " | " << g(r.release_energy_ratio, "%.3f") << " | "
      << (r.static_converged ? "tip " + g(r.static_tip_m * 1e3, "%.3g") + " mm" : "not converged") << " | "
      << g(r.tip_error) << " | " << g(r.transient_error) << " | " << g(r.rest_error) << " | "
      << note(r) << " |\n";
    std::cout << c.group << " " << c.value << ": " << (r.stable(c) ? "stable" : "NOT stable") << ", tip error "
              << g(r.tip_error) << ", transient " << g(r.transient_error) << ", rest error " << g(r.rest_error) << ", energy " << g(r.energy_ratio, "%.3f") << "/"
              << g(r.release_energy_ratio, "%.3f") << ", recovered " << r.recovered_steps << "/" << r.steps << "\n";
  }
  std::ofstream(out_md) << o.str();
  std::cout << "wrote " << out_md << "\n";
  return 0;
}
