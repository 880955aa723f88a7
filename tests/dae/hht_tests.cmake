# Tests of the sparse algebra, the KLU wrapper and the HHT integrator.
foreach(name sparse klu hht)
  if(EXISTS ${CMAKE_CURRENT_LIST_DIR}/test_${name}.cc)
    add_executable(dae_${name}_test ${CMAKE_CURRENT_LIST_DIR}/test_${name}.cc)
    target_link_libraries(dae_${name}_test PRIVATE mbdae_dae Eigen3::Eigen GTest::gtest_main)
    target_include_directories(dae_${name}_test PRIVATE ${PROJECT_SOURCE_DIR})
    gtest_discover_tests(dae_${name}_test DISCOVERY_TIMEOUT 60)
  endif()
endforeach()
