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
