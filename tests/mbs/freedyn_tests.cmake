# FreeDyn model files (mbs/freedyn.*) and the model writer (mbs/model_writer.*).
add_executable(mbs_test_freedyn ${CMAKE_CURRENT_LIST_DIR}/test_freedyn.cc)
target_link_libraries(mbs_test_freedyn PRIVATE mbdae_mbs mbdae_cli GTest::gtest_main)
target_compile_definitions(mbs_test_freedyn PRIVATE MBDAE_SOURCE_DIR="${PROJECT_SOURCE_DIR}")
gtest_discover_tests(mbs_test_freedyn)

# `mbdae convert`: exit codes, files and messages.
set(_fd_convert ${CMAKE_COMMAND} -DMBDAE=$<TARGET_FILE:mbdae>)
add_test(NAME freedyn.convert_oscillator_exit_0
         COMMAND ${_fd_convert} -DWORKDIR=${CMAKE_CURRENT_BINARY_DIR}/freedyn_run/oscillator
                 -DMODEL=${PROJECT_SOURCE_DIR}/examples/freedyn/oscillator.fds -DEXPECT=0
                 -P ${CMAKE_CURRENT_LIST_DIR}/freedyn_convert.cmake)
add_test(NAME freedyn.convert_yaml_exit_0
         COMMAND ${_fd_convert} -DWORKDIR=${CMAKE_CURRENT_BINARY_DIR}/freedyn_run/pendulum
                 -DMODEL=${PROJECT_SOURCE_DIR}/examples/pendulum.yaml -DEXPECT=0 -DCHECK_COMMAND=check
                 -P ${CMAKE_CURRENT_LIST_DIR}/freedyn_convert.cmake)
add_test(NAME freedyn.convert_unknown_block_exit_2
         COMMAND ${_fd_convert} -DWORKDIR=${CMAKE_CURRENT_BINARY_DIR}/freedyn_run/unknown_block
                 -DMODEL=${CMAKE_CURRENT_LIST_DIR}/models/freedyn/unknown_block.fds -DEXPECT=2
                 "-DMESSAGE=${CMAKE_CURRENT_LIST_DIR}/models/freedyn/unknown_block.fds:12:1: Force 'tyre': block type 'Force Tire' is not read"
                 -P ${CMAKE_CURRENT_LIST_DIR}/freedyn_convert.cmake)

# Acceptance 2, .fds half: .fds models (oscillator, pendulum) and their YAML twins give the same results.
add_test(NAME freedyn.simulate_fds_equals_yaml
         COMMAND ${MBDAE_PYTHON} -m pytest -q -s -p no:cacheprovider ${CMAKE_CURRENT_LIST_DIR}/test_freedyn_simulate.py)
set_tests_properties(freedyn.simulate_fds_equals_yaml PROPERTIES
  ENVIRONMENT "MBDAE_BIN=$<TARGET_FILE:mbdae>;MBDAE_SOURCE_DIR=${PROJECT_SOURCE_DIR}" TIMEOUT 300)
