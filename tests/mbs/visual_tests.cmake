# Visual geometry: loader, writer, FreeDyn geometry, the default drawing.
add_executable(mbs_test_visual ${CMAKE_CURRENT_LIST_DIR}/test_visual.cc)
target_link_libraries(mbs_test_visual PRIVATE mbdae_mbs GTest::gtest_main)
gtest_discover_tests(mbs_test_visual)
