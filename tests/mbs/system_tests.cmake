# Tests of mbs/kinematics and mbs/system (the multibody DAE).
add_executable(mbs_test_kinematics ${CMAKE_CURRENT_LIST_DIR}/test_kinematics.cc)
target_link_libraries(mbs_test_kinematics PRIVATE mbdae_mbs GTest::gtest_main)
gtest_discover_tests(mbs_test_kinematics)

add_executable(mbs_test_system ${CMAKE_CURRENT_LIST_DIR}/test_system.cc)
target_include_directories(mbs_test_system PRIVATE ${PROJECT_SOURCE_DIR})
target_link_libraries(mbs_test_system PRIVATE mbdae_mbs GTest::gtest_main)
gtest_discover_tests(mbs_test_system)
