# Fails if a source includes a project header from a layer it may not use
# (docs/architecture.md). Layers, lowest first; each may use those below it:
#   core  <  io  <  idl  <  { service (the run library), clients }  <  service/app
# The run library and the clients never include each other; the `fiberfem` program
# (service/app/) may use every layer. Project headers are named from the source root
# ("core/...", "io/...", "idl/...", "service/...", "clients/..."); the generated IDL
# headers (control.h, mesh.h, status.h) count as idl/.
# Usage: cmake -DSOURCE_DIR=<root> -P check_layers.cmake
cmake_minimum_required(VERSION 3.25)
set(layers core io idl service clients)
set(allowed_core core)
set(allowed_io core io)
set(allowed_idl core io idl)
set(allowed_service core io idl service)
set(allowed_clients core io idl clients)
set(bad "")
set(count 0)
foreach(layer ${layers})
  file(GLOB_RECURSE sources ${SOURCE_DIR}/${layer}/*.hpp ${SOURCE_DIR}/${layer}/*.cpp ${SOURCE_DIR}/${layer}/*.in)
  foreach(f ${sources})
    if(f MATCHES "/service/app/")
      continue()  # the program: every layer
    endif()
    math(EXPR count "${count} + 1")
    file(STRINGS ${f} lines REGEX "^[ \t]*#[ \t]*include[ \t]*\"")
    foreach(l ${lines})
      string(REGEX REPLACE "^[ \t]*#[ \t]*include[ \t]*\"([^\"]+)\".*" "\\1" inc "${l}")
      if(inc MATCHES "^(control|mesh|status)\\.h$")
        set(target idl)
      elseif(inc MATCHES "^([a-z]+)/")
        set(target ${CMAKE_MATCH_1})
      else()
        continue()  # a header beside the file
      endif()
      if(NOT target IN_LIST layers)
        continue()  # a system or third-party header in quotes
      endif()
      if(NOT target IN_LIST allowed_${layer})
        file(RELATIVE_PATH rel ${SOURCE_DIR} ${f})
        list(APPEND bad "${rel} (layer ${layer}) includes ${inc} (layer ${target})")
      endif()
    endforeach()
  endforeach()
endforeach()
if(bad)
  list(JOIN bad "\n  " text)
  message(FATAL_ERROR "includes across layers (docs/architecture.md):\n  ${text}")
endif()
message(STATUS "layers: ${count} sources include only their own and lower layers")
