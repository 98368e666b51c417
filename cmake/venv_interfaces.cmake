# Included after project() by `make install` (CMAKE_PROJECT_INCLUDE) when it builds an interface
# package into the venv. colcon builds are untouched: they build every generator, as ROS does.
#
# 1. Only the generators Python needs: the C code, the C type supports and the Python modules
#    (rclpy hands DDS the C type support; Fast DDS's rmw takes it). The C++ headers and type
#    supports are left out: nothing in the venv compiles C++ against our messages.
#    task_manager_msgs: 84 s -> 60 s on 2 cores (41 s with EmPy 3.3.4, ros-constraints.txt).
# 2. The generated sources compiled in batches (a unity build), which parses the DDS headers
#    once a batch rather than once a file. rosidl_generator_c's sources each define the same
#    static names (type hashes of the types they use), so that target stays one file at a time.

# The generators registered so far are read when rosidl_generate_interfaces runs them: drop the
# C++ ones at each read.
variable_watch(AMENT_EXTENSIONS_rosidl_generate_idl_interfaces _task_manager_python_generators)
macro(_task_manager_python_generators _variable _access _value)
  if("${_access}" STREQUAL "READ_ACCESS")
    list(FILTER AMENT_EXTENSIONS_rosidl_generate_idl_interfaces EXCLUDE REGEX "_cpp:")
  endif()
endmacro()

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

# 3. rosidl_generator_py's command waits for the target of every other generator (its comment:
#    the IDL files could be generated files), though it reads only the IDL files, which
#    rosidl_adapter writes at configure time: it runs beside the C generators rather than alone
#    after them (task_manager_msgs: the last 11 s of its build on one core). Its compiled
#    modules still wait for the C type supports they link.
variable_watch(_custom_command _task_manager_python_generator_sooner)
macro(_task_manager_python_generator_sooner _variable _access _value)
  if("${_access}" STREQUAL "READ_ACCESS")
    string(REPLACE "DEPENDS \${target_dependencies} \${rosidl_generate_interfaces_TARGET}"
      "DEPENDS \${target_dependencies}" _custom_command "${_custom_command}")
  endif()
endmacro()
