# The interface wheels on PyPI export Python generator targets whose include directories are
# paths on the machine that built the wheels (/opt/python/...); CMake refuses imported targets
# with include directories that do not exist. At the end of configuring, keep only the ones
# that exist here (generator expressions are kept as they are).
function(coverage_ros_keep_existing_include_dirs)
  get_directory_property(targets DIRECTORY "${CMAKE_SOURCE_DIR}" IMPORTED_TARGETS)
  foreach(target IN LISTS targets)
    get_target_property(dirs ${target} INTERFACE_INCLUDE_DIRECTORIES)
    if(dirs)
      set(existing "")
      foreach(dir IN LISTS dirs)
        if(dir MATCHES "^\\$<" OR EXISTS "${dir}")
          list(APPEND existing "${dir}")
        endif()
      endforeach()
      set_target_properties(${target} PROPERTIES INTERFACE_INCLUDE_DIRECTORIES "${existing}")
    endif()
  endforeach()
endfunction()
cmake_language(DEFER DIRECTORY "${CMAKE_SOURCE_DIR}" CALL coverage_ros_keep_existing_include_dirs)
