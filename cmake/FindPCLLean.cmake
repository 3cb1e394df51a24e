# Finds the PCL libraries this project uses, without PCL's CMake package (which, on Debian 12,
# pulls in VTK and fails on VTK's MPI target). Defines imported targets PCLLean::<component>.
#   find_package(PCLLean COMPONENTS common io filters search kdtree features)
find_path(PCLLean_INCLUDE_DIR pcl/point_types.h PATH_SUFFIXES pcl-1.14 pcl-1.13 pcl-1.12 pcl-1.11 pcl-1.10)
find_package(Boost QUIET)
set(PCLLean_FOUND TRUE)
foreach(comp IN LISTS PCLLean_FIND_COMPONENTS)
  find_library(PCLLean_${comp}_LIBRARY NAMES pcl_${comp})
  if(NOT PCLLean_${comp}_LIBRARY OR NOT PCLLean_INCLUDE_DIR)
    set(PCLLean_FOUND FALSE)
    if(PCLLean_FIND_REQUIRED)
      message(FATAL_ERROR "PCL component ${comp} not found (install libpcl-dev)")
    endif()
    continue()
  endif()
  if(NOT TARGET PCLLean::${comp})
    add_library(PCLLean::${comp} UNKNOWN IMPORTED)
    set_target_properties(PCLLean::${comp} PROPERTIES
      IMPORTED_LOCATION "${PCLLean_${comp}_LIBRARY}"
      INTERFACE_INCLUDE_DIRECTORIES "${PCLLean_INCLUDE_DIR}"
      INTERFACE_SYSTEM_INCLUDE_DIRECTORIES "${PCLLean_INCLUDE_DIR}")
    target_link_libraries(PCLLean::${comp} INTERFACE Eigen3::Eigen)
    if(Boost_FOUND)
      target_link_libraries(PCLLean::${comp} INTERFACE Boost::headers)
    endif()
  endif()
endforeach()
