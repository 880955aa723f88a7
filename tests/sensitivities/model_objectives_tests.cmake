# Tests of sensitivities/model_objectives (objectives of a model file).
add_executable(sens_test_model_objectives ${CMAKE_CURRENT_LIST_DIR}/test_model_objectives.cc)
target_include_directories(sens_test_model_objectives PRIVATE ${PROJECT_SOURCE_DIR})
target_link_libraries(sens_test_model_objectives PRIVATE mbdae_sensitivities mbdae_mbs GTest::gtest_main)
gtest_discover_tests(sens_test_model_objectives)
