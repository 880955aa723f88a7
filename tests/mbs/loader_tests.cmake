# Tests of the model loader, expressions and primitive mass properties.
foreach(name expression loader geometry)
  add_executable(mbs_test_${name} ${CMAKE_CURRENT_LIST_DIR}/test_${name}.cc)
  target_link_libraries(mbs_test_${name} PRIVATE mbdae_mbs GTest::gtest_main)
  gtest_discover_tests(mbs_test_${name})
endforeach()
# The loader test reads verification/malformed/ and tests/mbs/models/ of the source tree.
target_compile_definitions(mbs_test_loader PRIVATE MBDAE_SOURCE_DIR="${PROJECT_SOURCE_DIR}")
# Input checks (inertia, axes, non-finite force values, settings, library paths).
add_executable(mbs_test_input_checks ${CMAKE_CURRENT_LIST_DIR}/test_input_checks.cc)
target_link_libraries(mbs_test_input_checks PRIVATE mbdae_mbs GTest::gtest_main)
gtest_discover_tests(mbs_test_input_checks)
# Names looked up through the loader's indices (joints, forces, reaction measures' joints).
add_executable(mbs_test_loader_names ${CMAKE_CURRENT_LIST_DIR}/test_loader_names.cc)
target_link_libraries(mbs_test_loader_names PRIVATE mbdae_mbs GTest::gtest_main)
gtest_discover_tests(mbs_test_loader_names)
