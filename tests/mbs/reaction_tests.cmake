# Tests of mbs/reaction (reaction measures) and of objectives in the model file.
add_executable(mbs_test_reaction ${CMAKE_CURRENT_LIST_DIR}/test_reaction.cc)
target_include_directories(mbs_test_reaction PRIVATE ${PROJECT_SOURCE_DIR})
target_link_libraries(mbs_test_reaction PRIVATE mbdae_mbs mbdae_driver GTest::gtest_main)
gtest_discover_tests(mbs_test_reaction)
