# Exact parameter derivatives of the multibody system (mbs/sensitivity_parameters.*,
# MultibodySystem parameter matrices, Expression::EvaluateDirectional, Spline::Tangent).
add_executable(mbs_test_parameter_derivatives ${CMAKE_CURRENT_LIST_DIR}/test_parameter_derivatives.cc)
target_link_libraries(mbs_test_parameter_derivatives PRIVATE mbdae_mbs GTest::gtest_main)
gtest_discover_tests(mbs_test_parameter_derivatives)
