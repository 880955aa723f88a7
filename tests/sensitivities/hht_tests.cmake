# The HHT discrete adjoint and direct differentiation against finite differences of
# whole runs.
add_executable(sens_hht_test ${CMAKE_CURRENT_LIST_DIR}/test_hht_sensitivity.cc)
target_link_libraries(sens_hht_test PRIVATE mbdae_sensitivities mbdae_mbs mbdae_dae GTest::gtest_main)
target_include_directories(sens_hht_test PRIVATE ${PROJECT_SOURCE_DIR})
target_compile_definitions(sens_hht_test PRIVATE MBDAE_SOURCE_DIR="${PROJECT_SOURCE_DIR}")
gtest_discover_tests(sens_hht_test DISCOVERY_TIMEOUT 60)
# Checkpointing: restore of the HHT integrator, gradients over checkpointed trajectories.
add_executable(sens_hht_checkpoint_test ${CMAKE_CURRENT_LIST_DIR}/test_hht_checkpoint.cc)
target_link_libraries(sens_hht_checkpoint_test PRIVATE mbdae_sensitivities mbdae_mbs mbdae_dae GTest::gtest_main)
target_include_directories(sens_hht_checkpoint_test PRIVATE ${PROJECT_SOURCE_DIR})
target_compile_definitions(sens_hht_checkpoint_test PRIVATE MBDAE_SOURCE_DIR="${PROJECT_SOURCE_DIR}")
gtest_discover_tests(sens_hht_checkpoint_test DISCOVERY_TIMEOUT 60)
