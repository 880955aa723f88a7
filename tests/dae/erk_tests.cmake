# Tests of the explicit Runge-Kutta integrator on the index-1 form (dae/erk.h).
add_executable(dae_erk_test ${CMAKE_CURRENT_LIST_DIR}/test_erk.cc)
target_link_libraries(dae_erk_test PRIVATE mbdae_dae GTest::gtest_main)
target_include_directories(dae_erk_test PRIVATE ${PROJECT_SOURCE_DIR})
gtest_discover_tests(dae_erk_test DISCOVERY_TIMEOUT 60)
