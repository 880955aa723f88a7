# Tests of mbs/measure_kinematics (measures with exact first and second derivatives).
add_executable(mbs_test_measure_kinematics ${CMAKE_CURRENT_LIST_DIR}/test_measure_kinematics.cc)
target_include_directories(mbs_test_measure_kinematics PRIVATE ${PROJECT_SOURCE_DIR})
target_link_libraries(mbs_test_measure_kinematics PRIVATE mbdae_mbs GTest::gtest_main)
gtest_discover_tests(mbs_test_measure_kinematics)
