# Warnings and optimisation flags shared by every fiberfem target, through one INTERFACE
# target instead of global flags.
add_library(fiberfem_compile_options INTERFACE)
add_library(fiberfem::compile_options ALIAS fiberfem_compile_options)
target_compile_options(fiberfem_compile_options INTERFACE
  $<$<CXX_COMPILER_ID:GNU,Clang>:-Wall -Wextra -Wpedantic>
  $<$<CXX_COMPILER_ID:GNU>:-Wno-maybe-uninitialized>)
if(FIBERFEM_NATIVE)
  target_compile_options(fiberfem_compile_options INTERFACE
    $<$<CXX_COMPILER_ID:GNU,Clang>:-march=native>)
endif()
