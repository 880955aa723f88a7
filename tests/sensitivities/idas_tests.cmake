# IDAS forward and adjoint sensitivities against central differences of whole IDA runs.
add_executable(sens_idas_test ${CMAKE_CURRENT_LIST_DIR}/test_idas_sensitivity.cc)
target_link_libraries(sens_idas_test PRIVATE mbdae_sensitivities mbdae_dae GTest::gtest_main)
target_include_directories(sens_idas_test PRIVATE ${PROJECT_SOURCE_DIR})
gtest_discover_tests(sens_idas_test DISCOVERY_TIMEOUT 60)
# The IDAS adjoint against the forward method on models with rotating bodies (Euler
# parameters: singular mass matrix), through the gradient driver.
add_executable(sens_idas_rotating_test ${CMAKE_CURRENT_LIST_DIR}/test_idas_adjoint_rotating.cc)
target_link_libraries(sens_idas_rotating_test PRIVATE mbdae_driver GTest::gtest_main)
target_include_directories(sens_idas_rotating_test PRIVATE ${PROJECT_SOURCE_DIR})
gtest_discover_tests(sens_idas_rotating_test DISCOVERY_TIMEOUT 60)
