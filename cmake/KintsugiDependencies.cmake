# Finds kintsugi's dependencies (all Debian packages) and links them to a target.
# Used both by the build tree and by the installed kintsugiConfig.cmake.
include(CMakeFindDependencyMacro)

macro(kintsugi_find_dependencies)
  find_dependency(Eigen3 3.4 NO_MODULE)
  find_dependency(nanoflann)
  find_dependency(Boost 1.74)
  # CGAL's own finder warns about the build type; it is header-only here.
  set(CGAL_DO_NOT_WARN_ABOUT_CMAKE_BUILD_TYPE TRUE)
  find_dependency(CGAL)
  if(KINTSUGI_REQUIRE_TBB)
    find_dependency(TBB CONFIG)
  elseif(NOT DEFINED KINTSUGI_USE_TBB OR KINTSUGI_USE_TBB)
    find_package(TBB QUIET CONFIG)
  endif()
endmacro()

macro(kintsugi_link_dependencies target)
  kintsugi_find_dependencies()
  target_link_libraries(${target} INTERFACE Eigen3::Eigen nanoflann::nanoflann Boost::boost CGAL::CGAL)
  if(TBB_FOUND)
    target_link_libraries(${target} INTERFACE TBB::tbb)
    target_compile_definitions(${target} INTERFACE KINTSUGI_HAS_TBB)
  endif()
endmacro()
