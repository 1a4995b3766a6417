# The ROS 2 wheels on PyPI export Python-binding targets whose include directories point at the
# machine the wheels were built on (/opt/python/...). Swap those for this interpreter's own
# Python and NumPy headers so that an interface package also builds in a plain virtual
# environment. Include it after the find_package calls of the package's dependencies.
find_package(Python3 COMPONENTS Interpreter Development.Module NumPy)
if(Python3_FOUND)
  get_property(imported_targets DIRECTORY PROPERTY IMPORTED_TARGETS)
  foreach(target IN LISTS imported_targets)
    get_target_property(include_dirs ${target} INTERFACE_INCLUDE_DIRECTORIES)
    if(include_dirs AND "${include_dirs}" MATCHES "/opt/python/")
      list(FILTER include_dirs EXCLUDE REGEX "^/opt/python/")
      list(APPEND include_dirs ${Python3_INCLUDE_DIRS} ${Python3_NumPy_INCLUDE_DIRS})
      set_target_properties(${target} PROPERTIES INTERFACE_INCLUDE_DIRECTORIES "${include_dirs}")
    endif()
  endforeach()
endif()
