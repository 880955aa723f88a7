# Tests of the two-marker force laws: user forces through the C ABI (mbs/user_force.*,
# api/mbdae_user_force.h, examples/user_force) and bushings (mbs/bushing.*).
add_library(mbdae_test_bad_abi MODULE ${CMAKE_CURRENT_LIST_DIR}/user_force_bad_library.c)
target_include_directories(mbdae_test_bad_abi PRIVATE ${PROJECT_SOURCE_DIR})
target_compile_definitions(mbdae_test_bad_abi PRIVATE BAD_ABI_VERSION)
set_target_properties(mbdae_test_bad_abi PROPERTIES C_VISIBILITY_PRESET hidden)
add_library(mbdae_test_no_version MODULE ${CMAKE_CURRENT_LIST_DIR}/user_force_bad_library.c)
target_include_directories(mbdae_test_no_version PRIVATE ${PROJECT_SOURCE_DIR})
set_target_properties(mbdae_test_no_version PROPERTIES C_VISIBILITY_PRESET hidden)

add_executable(mbs_test_user_force ${CMAKE_CURRENT_LIST_DIR}/test_user_force.cc)
target_link_libraries(mbs_test_user_force PRIVATE mbdae_mbs GTest::gtest_main)
add_dependencies(mbs_test_user_force mbdae_example_user_force mbdae_test_bad_abi
                 mbdae_test_no_version)
target_compile_definitions(mbs_test_user_force PRIVATE
  MBDAE_EXAMPLE_USER_FORCE_LIBRARY="$<TARGET_FILE:mbdae_example_user_force>"
  MBDAE_BAD_ABI_LIBRARY="$<TARGET_FILE:mbdae_test_bad_abi>"
  MBDAE_NO_VERSION_LIBRARY="$<TARGET_FILE:mbdae_test_no_version>")
gtest_discover_tests(mbs_test_user_force)

add_executable(mbs_test_bushing ${CMAKE_CURRENT_LIST_DIR}/test_bushing.cc)
target_link_libraries(mbs_test_bushing PRIVATE mbdae_mbs GTest::gtest_main)
gtest_discover_tests(mbs_test_bushing)
