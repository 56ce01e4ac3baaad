# `cmake --install build --prefix P`: the libraries, the public headers, the CLI and the CMake package that
# find_package(lancer 0.1 CONFIG) reads (docs/packaging.md).
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

# lancer::lancer as one shared library made of the static libraries' objects, so that a consumer links one
# file and finds none of its private dependencies. The static libraries are linked too, for their
# dependencies (assimp, libpng, OpenEXR, oneTBB, Embree, the CUDA runtime): their own members are never
# pulled, every symbol being defined by the objects already.
set(lancer_shared_objects)
foreach(part IN LISTS lancer_parts)
  list(APPEND lancer_shared_objects $<TARGET_OBJECTS:${part}>)
endforeach()
if(TARGET lancer_kernels_avx512)
  list(APPEND lancer_shared_objects $<TARGET_OBJECTS:lancer_kernels_avx512>)
endif()
add_library(lancer_shared SHARED ${lancer_shared_objects})
target_link_libraries(lancer_shared PRIVATE ${lancer_parts})
target_include_directories(lancer_shared PUBLIC $<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>)
set_target_properties(lancer_shared PROPERTIES
  OUTPUT_NAME lancer EXPORT_NAME lancer LINKER_LANGUAGE CXX
  VERSION ${PROJECT_VERSION} SOVERSION ${PROJECT_VERSION_MAJOR}.${PROJECT_VERSION_MINOR}
  # The dependencies' own symbols stay inside.
  LINK_OPTIONS "-Wl,--exclude-libs,ALL")
set_target_properties(lancer_core PROPERTIES EXPORT_NAME core)
target_include_directories(lancer_core PUBLIC $<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>)

get_target_property(lancer_core_links lancer_core LINK_LIBRARIES)
if("TBB::tbb" IN_LIST lancer_core_links)
  set(lancer_core_uses_tbb ON)
else()
  set(lancer_core_uses_tbb OFF)
endif()

install(TARGETS lancer_shared lancer_core EXPORT lancerTargets
  LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
  ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
  RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
install(DIRECTORY ${PROJECT_SOURCE_DIR}/include/lancer DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
install(EXPORT lancerTargets NAMESPACE lancer:: DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/lancer)
configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/lancerConfig.cmake.in
  ${PROJECT_BINARY_DIR}/lancerConfig.cmake INSTALL_DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/lancer)
# 0.x: a minor version may change the API, so only the same minor version is compatible.
write_basic_package_version_file(${PROJECT_BINARY_DIR}/lancerConfigVersion.cmake
  COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/lancerConfig.cmake ${PROJECT_BINARY_DIR}/lancerConfigVersion.cmake
  DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/lancer)
if(TARGET lancer_cli)
  install(TARGETS lancer_cli RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
endif()
