# Acceptance runs of the time- and state-dependent elements (verification/): force
# expressions over measures (oscillator), motion and gear constraints.
foreach(problem oscillator crank_motion gear)
  if(EXISTS ${PROJECT_SOURCE_DIR}/verification/${problem}/run.py)
    add_test(NAME verification.${problem}
             COMMAND ${MBDAE_PYTHON} ${PROJECT_SOURCE_DIR}/verification/${problem}/run.py
                     --mbdae $<TARGET_FILE:mbdae>)
    set_tests_properties(verification.${problem} PROPERTIES
      ENVIRONMENT "MBDAE_VERIFICATION_OUT=${PROJECT_BINARY_DIR}/verification/${problem};MPLBACKEND=Agg"
      TIMEOUT 300)
  endif()
endforeach()

add_executable(mbs_test_motion_gear ${CMAKE_CURRENT_LIST_DIR}/test_motion_gear.cc)
target_link_libraries(mbs_test_motion_gear PRIVATE mbdae_mbs GTest::gtest_main)
gtest_discover_tests(mbs_test_motion_gear)

# Bushing and user force elements in model files and in the system.
add_executable(mbs_test_two_marker_elements ${CMAKE_CURRENT_LIST_DIR}/test_two_marker_elements.cc)
target_include_directories(mbs_test_two_marker_elements PRIVATE ${PROJECT_SOURCE_DIR})
target_link_libraries(mbs_test_two_marker_elements PRIVATE mbdae_mbs GTest::gtest_main)
add_dependencies(mbs_test_two_marker_elements mbdae_example_user_force)
target_compile_definitions(mbs_test_two_marker_elements PRIVATE
  MBDAE_EXAMPLE_USER_FORCE_LIBRARY="$<TARGET_FILE:mbdae_example_user_force>")
gtest_discover_tests(mbs_test_two_marker_elements)

# Acceptance 6: the example user-force library loaded by a model reproduces the built-in
# spring_damper (verification/user_force/; the model is copied next to the built library).
add_test(NAME verification.user_force
         COMMAND ${MBDAE_PYTHON} ${PROJECT_SOURCE_DIR}/verification/user_force/run.py
                 --mbdae $<TARGET_FILE:mbdae> --library $<TARGET_FILE:mbdae_example_user_force>)
set_tests_properties(verification.user_force PROPERTIES
  ENVIRONMENT "MBDAE_VERIFICATION_OUT=${PROJECT_BINARY_DIR}/verification/user_force;MPLBACKEND=Agg"
  TIMEOUT 300)
