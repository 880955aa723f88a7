# Tests of mbs/mesh (STL/OBJ reading, mass properties of closed meshes). The test meshes
# are written at run time into the test's temporary directory.
add_executable(mbs_test_mesh ${CMAKE_CURRENT_LIST_DIR}/test_mesh.cc)
target_link_libraries(mbs_test_mesh PRIVATE mbdae_mbs GTest::gtest_main)
gtest_discover_tests(mbs_test_mesh)
