#include "core/team_affinity.hpp"

#include <omp.h>
#include <sched.h>

namespace fiberfem::core {
namespace {

// The CPUs the process may use, read once (before any team thread was moved).
const cpu_set_t& process_cpus() {
  static const cpu_set_t cpus = [] {
    cpu_set_t s;
    CPU_ZERO(&s);
    if (sched_getaffinity(0, sizeof s, &s) != 0) CPU_ZERO(&s);
    return s;
  }();
  return cpus;
}

}  // namespace

int current_cpu() {
  (void)process_cpus();  // read on the caller's thread, before a team thread is moved
  return sched_getcpu();
}

void keep_team_apart(int caller_cpu) {
  thread_local int kept_from = -1;  // the CPU this thread was last kept from
  if (caller_cpu < 0 || caller_cpu >= CPU_SETSIZE || omp_get_thread_num() == 0 || kept_from == caller_cpu) return;
  cpu_set_t allowed = process_cpus();
  if (!CPU_ISSET(caller_cpu, &allowed) || CPU_COUNT(&allowed) < 2) return;
  CPU_CLR(caller_cpu, &allowed);
  if (sched_setaffinity(0, sizeof allowed, &allowed) == 0) kept_from = caller_cpu;
}

}  // namespace fiberfem::core
