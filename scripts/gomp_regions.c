// Time spent in each OpenMP parallel region of a process, for finding where the threads of
// a step wait (docs/performance.md, "Time in parallel regions"). An LD_PRELOAD wrapper of
// libgomp's GOMP_parallel: per outlined region function, the calls and the wall time from
// fork to join, printed at exit with the function's offset in its binary (addr2line -f -C
// -e BINARY 0xOFFSET names it).
//
//   gcc -O2 -shared -fPIC -o build/gomp_regions.so scripts/gomp_regions.c -ldl
//   LD_PRELOAD=build/gomp_regions.so build/release/tests/bench/bench_step ... --trace 2000
#define _GNU_SOURCE
#include <dlfcn.h>
#include <stdio.h>
#include <time.h>

enum { kMaxRegions = 128 };
static void* region_fn[kMaxRegions];
static long region_calls[kMaxRegions];
static double region_seconds[kMaxRegions];
static int num_regions = 0;

static double now(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return t.tv_sec + 1e-9 * t.tv_nsec;
}

// Called by the thread that opens the region (regions nest only as serialised ones here).
void GOMP_parallel(void (*fn)(void*), void* data, unsigned num_threads, unsigned flags) {
  static void (*real)(void (*)(void*), void*, unsigned, unsigned) = 0;
  if (!real) real = (void (*)(void (*)(void*), void*, unsigned, unsigned))dlsym(RTLD_NEXT, "GOMP_parallel");
  const double t0 = now();
  real(fn, data, num_threads, flags);
  const double dt = now() - t0;
  int i = 0;
  while (i < num_regions && region_fn[i] != (void*)fn) ++i;
  if (i == num_regions && num_regions < kMaxRegions) region_fn[num_regions++] = (void*)fn;
  if (i < kMaxRegions) {
    ++region_calls[i];
    region_seconds[i] += dt;
  }
}

__attribute__((destructor)) static void report(void) {
  fprintf(stderr, "gomp_regions: calls, total ms, us per call, binary, offset of the region's function\n");
  for (int i = 0; i < num_regions; ++i) {
    Dl_info info;
    const char* file = "?";
    unsigned long offset = 0;
    if (dladdr(region_fn[i], &info)) {
      file = info.dli_fname;
      offset = (unsigned long)((char*)region_fn[i] - (char*)info.dli_fbase);
    }
    fprintf(stderr, "gomp_regions: %8ld %10.3f %9.2f %s 0x%lx\n", region_calls[i], 1e3 * region_seconds[i],
            1e6 * region_seconds[i] / region_calls[i], file, offset);
  }
}
