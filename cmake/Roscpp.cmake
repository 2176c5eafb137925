# ROS 1's client library as Debian packages it (libroscpp-dev, libtopic-tools-dev:
# plain include and library folders, no CMake package of its own), as the
# imported target Ros1::roscpp. DCL_WITH_ROS1: ON (required), OFF, or AUTO
# (built when found); DCL_HAVE_ROS1 says whether it was.
set(DCL_WITH_ROS1 AUTO CACHE STRING "ROS 1 live robots through roscpp: ON, OFF or AUTO")
set(DCL_HAVE_ROS1 OFF)
if(NOT DCL_WITH_ROS1 STREQUAL "OFF")
  find_path(ROSCPP_INCLUDE_DIR ros/ros.h)
  find_path(TOPIC_TOOLS_INCLUDE_DIR topic_tools/shape_shifter.h)
  set(_ros1_libraries)
  set(_ros1_found TRUE)
  if(NOT ROSCPP_INCLUDE_DIR OR NOT TOPIC_TOOLS_INCLUDE_DIR)
    set(_ros1_found FALSE)
  endif()
  foreach(lib roscpp topic_tools roscpp_serialization rostime cpp_common xmlrpcpp rosconsole)
    find_library(ROS1_LIB_${lib} ${lib})
    list(APPEND _ros1_libraries ${ROS1_LIB_${lib}})
    if(NOT ROS1_LIB_${lib})
      set(_ros1_found FALSE)
    endif()
  endforeach()
  if(_ros1_found)
    set(DCL_HAVE_ROS1 ON)
    add_library(Ros1::roscpp INTERFACE IMPORTED)
    set_target_properties(Ros1::roscpp PROPERTIES
      INTERFACE_INCLUDE_DIRECTORIES "${ROSCPP_INCLUDE_DIR};${TOPIC_TOOLS_INCLUDE_DIR}"
      INTERFACE_LINK_LIBRARIES "${_ros1_libraries}")
    message(STATUS "ROS 1 (roscpp): found; robot --ros1 is built")
  elseif(DCL_WITH_ROS1 STREQUAL "ON")
    message(FATAL_ERROR "DCL_WITH_ROS1=ON but roscpp was not found: install libroscpp-dev "
                        "and libtopic-tools-dev (scripts/setup does)")
  else()
    message(STATUS "ROS 1 (roscpp): not found; robot --ros1 says what to install")
  endif()
endif()
