# One place for every third-party dependency. All come from Debian 12's archive
# (scripts/install-deps.sh installs them).

find_package(Eigen3 3.4 REQUIRED NO_MODULE)
find_package(nlohmann_json 3.10 REQUIRED)
find_package(CLI11 REQUIRED)
find_package(TBB REQUIRED)
find_package(TinyGLTF REQUIRED)
find_package(assimp REQUIRED)
find_package(embree 3 REQUIRED)

# CGAL: only its kernel (LGPL) is used, for exact orientation predicates.
# Its GPL packages (meshes, AABB trees, ...) are never included.
set(CGAL_DO_NOT_WARN_ABOUT_CMAKE_BUILD_TYPE TRUE)
find_package(CGAL REQUIRED)

# OpenSubdiv (Catmull-Clark refinement of control cages). Debian's CMake
# package for it is broken, so find the CPU library and headers directly.
find_library(OSD_CPU_LIBRARY osdCPU REQUIRED)
find_path(OSD_INCLUDE_DIR opensubdiv/far/topologyRefiner.h REQUIRED)
add_library(opensubdiv::cpu UNKNOWN IMPORTED)
set_target_properties(opensubdiv::cpu PROPERTIES IMPORTED_LOCATION "${OSD_CPU_LIBRARY}"
                                                 INTERFACE_INCLUDE_DIRECTORIES "${OSD_INCLUDE_DIR}")
