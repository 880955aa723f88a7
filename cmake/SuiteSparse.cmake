# Imported targets for the SuiteSparse parts we use (Debian's libsuitesparse-dev
# ships neither CMake configs nor pkg-config files for version 5.x).
find_path(SUITESPARSE_INCLUDE_DIR klu.h PATH_SUFFIXES suitesparse REQUIRED)
foreach(lib klu amd colamd btf spqr cholmod suitesparseconfig)
  find_library(SUITESPARSE_${lib}_LIBRARY NAMES ${lib} REQUIRED)
  if(NOT TARGET SuiteSparse::${lib})
    add_library(SuiteSparse::${lib} UNKNOWN IMPORTED)
    set_target_properties(SuiteSparse::${lib} PROPERTIES
      IMPORTED_LOCATION "${SUITESPARSE_${lib}_LIBRARY}"
      INTERFACE_INCLUDE_DIRECTORIES "${SUITESPARSE_INCLUDE_DIR}")
  endif()
endforeach()
set_property(TARGET SuiteSparse::klu APPEND PROPERTY INTERFACE_LINK_LIBRARIES
  SuiteSparse::amd SuiteSparse::colamd SuiteSparse::btf SuiteSparse::suitesparseconfig)
set_property(TARGET SuiteSparse::spqr APPEND PROPERTY INTERFACE_LINK_LIBRARIES
  SuiteSparse::cholmod SuiteSparse::suitesparseconfig)
