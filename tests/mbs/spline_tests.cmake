# Tests of the splines (mbs/spline.*); the loader's splines are in test_loader.cc.
add_executable(mbs_test_spline ${CMAKE_CURRENT_LIST_DIR}/test_spline.cc)
target_link_libraries(mbs_test_spline PRIVATE mbdae_mbs GTest::gtest_main)
gtest_discover_tests(mbs_test_spline)
