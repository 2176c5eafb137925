# Debian's librosbag-storage-dev reads ROS1 bags without a ROS master, but its
# headers include pluginlib from Debian's ROS 2 packaging (nested include
# folders, no pkg-config file), so `pkg-config rosbag_storage` fails. This
# module makes the imported target Rosbag::storage from the parts that work.
find_path(ROSBAG_INCLUDE_DIR rosbag/bag.h REQUIRED)
set(_rosbag_include_dirs ${ROSBAG_INCLUDE_DIR})
foreach(sub pluginlib class_loader rcpputils rcutils ament_index_cpp)
  if(EXISTS /usr/include/${sub})
    list(APPEND _rosbag_include_dirs /usr/include/${sub})
  endif()
endforeach()
set(_rosbag_libraries)
foreach(lib rosbag_storage roscpp_serialization rostime cpp_common console_bridge)
  find_library(ROSBAG_LIB_${lib} ${lib} REQUIRED)
  list(APPEND _rosbag_libraries ${ROSBAG_LIB_${lib}})
endforeach()
add_library(Rosbag::storage INTERFACE IMPORTED)
set_target_properties(Rosbag::storage PROPERTIES
  INTERFACE_INCLUDE_DIRECTORIES "${_rosbag_include_dirs}"
  INTERFACE_LINK_LIBRARIES "${_rosbag_libraries}")
