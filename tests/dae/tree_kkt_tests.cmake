# The tree elimination of the acceleration-level matrix against KLU (dae/tree_kkt.h).
add_executable(dae_tree_kkt_test ${CMAKE_CURRENT_LIST_DIR}/test_tree_kkt.cc)
target_link_libraries(dae_tree_kkt_test PRIVATE mbdae_dae mbdae_mbs GTest::gtest_main)
target_include_directories(dae_tree_kkt_test PRIVATE ${PROJECT_SOURCE_DIR})
target_compile_definitions(dae_tree_kkt_test
                           PRIVATE MBDAE_TEST_MODELS="${PROJECT_SOURCE_DIR}/tests/app/models")
gtest_discover_tests(dae_tree_kkt_test DISCOVERY_TIMEOUT 60)
