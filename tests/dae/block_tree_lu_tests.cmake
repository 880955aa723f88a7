# The block tree elimination against dense LU and KLU, and HHT with it (dae/block_tree_lu.h).
add_executable(dae_block_tree_lu_test ${CMAKE_CURRENT_LIST_DIR}/test_block_tree_lu.cc)
target_link_libraries(dae_block_tree_lu_test PRIVATE mbdae_dae mbdae_mbs Eigen3::Eigen GTest::gtest_main)
target_include_directories(dae_block_tree_lu_test PRIVATE ${PROJECT_SOURCE_DIR})
target_compile_definitions(dae_block_tree_lu_test
                           PRIVATE MBDAE_TEST_MODELS="${PROJECT_SOURCE_DIR}/tests/app/models")
gtest_discover_tests(dae_block_tree_lu_test DISCOVERY_TIMEOUT 60)
