#pragma once
/// @file Keeps the threads of a parallel loop on different CPUs.
///
/// Why: libgomp's threads spin where they wait (at the end of a loop, for the others), and
/// a step runs dozens of loops. Beside a third busy process (even one at nice 19) the
/// scheduler moves a team thread now and then onto the CPU of another, where the spinning
/// one holds the CPU its partner needs: measured on two cores beside a nice-19 process,
/// the paper-size beam on two threads ran 6-34 steps/s instead of 700, with steps of up to
/// 3 s, and the accurate tier's element loop took 11-20 s instead of 0.1.
/// Binding every thread to a fixed CPU (OMP_PROC_BIND) prevents it but binds the process's
/// main thread too, so two one-thread processes started together share one CPU. Sleeping
/// at once instead of spinning (OMP_WAIT_POLICY=passive) prevents it but makes two threads
/// slower than one on a quiet machine (each loop waits for a sleeping thread to wake).
///
/// So only the other threads of a team are placed: each may use every CPU of the process
/// except the one the loop's caller runs on when the loop starts, and is moved only when
/// that CPU changed since its last loop. The caller stays free. Figures:
/// docs/performance.md, "Threads and a shared machine".

namespace fiberfem::core {

/// The CPU the calling thread runs on now (-1 if unknown). Call before opening a parallel
/// region and pass the value to keep_team_apart() inside it.
int current_cpu();

/// Call first thing in a parallel region, on every thread of the team, with the CPU the
/// region's caller ran on (current_cpu() before the region). A no-op on the caller's own
/// thread, for an unknown CPU, and when the process may use only one CPU.
void keep_team_apart(int caller_cpu);

}  // namespace fiberfem::core
