# Tests of the IDA integrator on the index-2 form and of consistent initial values.
foreach(name ida ida_limits ida_singular sparse_limits consistent)
  if(EXISTS ${CMAKE_CURRENT_LIST_DIR}/test_${name}.cc)
    add_executable(dae_${name}_test ${CMAKE_CURRENT_LIST_DIR}/test_${name}.cc)
    target_link_libraries(dae_${name}_test PRIVATE mbdae_dae GTest::gtest_main)
    target_include_directories(dae_${name}_test PRIVATE ${PROJECT_SOURCE_DIR})
    gtest_discover_tests(dae_${name}_test DISCOVERY_TIMEOUT 60)
  endif()
endforeach()
