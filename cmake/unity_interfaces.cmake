# Included after project() by `make install` (CMAKE_PROJECT_INCLUDE) when it builds an interface
# package into the venv: compile the generated sources in batches (a unity build), which parses
# the DDS headers once a batch rather than once a file. rosidl_generator_c's sources each define
# the same static names (type hashes of the types they use), so that target stays one file at a
# time. colcon builds are untouched.
set(CMAKE_UNITY_BUILD ON)
cmake_language(DEFER DIRECTORY ${CMAKE_SOURCE_DIR} CALL _task_manager_unity_exceptions)
function(_task_manager_unity_exceptions)
  get_directory_property(_targets DIRECTORY ${CMAKE_SOURCE_DIR} BUILDSYSTEM_TARGETS)
  foreach(_target IN LISTS _targets)
    if(_target MATCHES "__rosidl_generator_c$")
      set_target_properties(${_target} PROPERTIES UNITY_BUILD OFF)
    endif()
  endforeach()
endfunction()
