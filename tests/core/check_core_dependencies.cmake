# Fails if any file in core/ includes a header from outside Eigen, OpenMP, the standard
# library or core/ itself (no file formats, DDS, HDF5, logging, rendering in the engine).
file(GLOB_RECURSE sources ${CORE_DIR}/*.hpp ${CORE_DIR}/*.cpp)
# dlfcn.h: solvers/cholesky_factor.cpp looks up openblas_set_num_threads (no I/O; see there).
# sched.h: team_affinity.cpp keeps the other threads of a parallel loop off its caller's CPU.
# boost/graph/: header-only graph algorithms (sparse_system.cpp: reverse Cuthill-McKee numbering).
# boost/sort/spreadsort/: header-only radix sort (keyed_sort.cpp: the element orders).
# immintrin.h: the compiler's x86 intrinsics (corotated_linear_model.cpp: the element pass's
# AVX-512 gathers and fused multiply-adds; a portable loop elsewhere).
# amgcl/: header-only algebraic multigrid (amg_preconditioner.cpp; its math only, no amgcl/io).
set(allowed "^(Eigen/|amgcl/(adapter|backend|coarsening|relaxation|value_type|amg)|boost/graph/(compressed_sparse_row_graph|cuthill_mckee_ordering)\\.hpp|boost/sort/spreadsort/integer_sort\\.hpp|omp\\.h|immintrin\\.h|dlfcn\\.h|sched\\.h|core/|[a-z_]+$|cmath|cstdint|cstdio|cstddef|cstdlib|cstring|climits)")
set(bad "")
foreach(f ${sources})
  file(STRINGS ${f} lines REGEX "^[ \t]*#[ \t]*include")
  foreach(l ${lines})
    string(REGEX REPLACE "^[ \t]*#[ \t]*include[ \t]*[<\"]([^>\"]+)[>\"].*" "\\1" inc "${l}")
    if(NOT inc MATCHES "${allowed}")
      list(APPEND bad "${f}: ${inc}")
    endif()
  endforeach()
endforeach()
if(bad)
  message(FATAL_ERROR "core/ includes headers outside Eigen/OpenMP/std:\n${bad}")
endif()
message(STATUS "core/ includes only Eigen, OpenMP, the standard library and itself (${CMAKE_ARGC} ok)")
