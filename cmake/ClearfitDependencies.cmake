# Finds every library clearfit builds on. A missing one stops the configure step
# with the Debian package that provides it (scripts/bootstrap.sh installs them all).

function(clearfit_require found what package)
  if(NOT ${found})
    message(FATAL_ERROR
      "clearfit: ${what} was not found. Install it with:\n"
      "    apt-get install -y ${package}\n"
      "or run scripts/bootstrap.sh, which installs every dependency.")
  endif()
endfunction()

find_package(Eigen3 3.3 NO_MODULE QUIET)
clearfit_require(Eigen3_FOUND "Eigen3" libeigen3-dev)

set(CGAL_DO_NOT_WARN_ABOUT_CMAKE_BUILD_TYPE TRUE)
find_package(CGAL QUIET)
clearfit_require(CGAL_FOUND "CGAL" libcgal-dev)
include(CGAL_Eigen3_support)

find_package(OpenMesh CONFIG QUIET)  # CONFIG: CGAL ships a FindOpenMesh module that shadows it
clearfit_require(OpenMesh_FOUND "OpenMesh" libopenmesh-dev)

find_package(tinyobjloader QUIET)
clearfit_require(tinyobjloader_FOUND "tinyobjloader" libtinyobjloader-dev)

find_package(TinyGLTF QUIET)
clearfit_require(TinyGLTF_FOUND "tinygltf" libtinygltf-dev)

find_package(nlohmann_json 3 QUIET)
clearfit_require(nlohmann_json_FOUND "nlohmann-json" nlohmann-json3-dev)

find_package(embree 3 CONFIG QUIET)
clearfit_require(embree_FOUND "Embree 3" libembree-dev)

find_package(TBB CONFIG QUIET)
clearfit_require(TBB_FOUND "oneTBB" libtbb-dev)

find_package(CLI11 QUIET)
clearfit_require(CLI11_FOUND "CLI11" libcli11-dev)

find_package(yaml-cpp QUIET)
clearfit_require(yaml-cpp_FOUND "yaml-cpp" libyaml-cpp-dev)

find_package(OpenCV QUIET COMPONENTS core imgproc imgcodecs videoio video calib3d)
clearfit_require(OpenCV_FOUND "OpenCV (core imgproc imgcodecs videoio video calib3d)" libopencv-dev)

# FFmpeg's libraries (OpenCV is built on them too): clearfit decodes videos itself, to honour
# the colour matrix, range and rotation a phone writes and to decode on several threads.
find_package(PkgConfig QUIET)
if(PkgConfig_FOUND)
  pkg_check_modules(FFMPEG QUIET IMPORTED_TARGET libavformat libavcodec libswscale libavutil)
endif()
clearfit_require(FFMPEG_FOUND "FFmpeg (libavformat libavcodec libswscale libavutil)" "libavformat-dev libavcodec-dev libswscale-dev")

find_package(OpenSSL QUIET COMPONENTS Crypto)
clearfit_require(OpenSSL_FOUND "OpenSSL (libcrypto, for input hashes)" libssl-dev)

find_package(Boost 1.74 QUIET)
clearfit_require(Boost_FOUND "Boost (headers: Boost.Math for the study's statistics)" libboost-dev)

find_package(apriltag QUIET)
clearfit_require(apriltag_FOUND "AprilTag" libapriltag-dev)

# lib3mf 1.8 (Debian 12) ships neither a CMake config nor a usable pkg-config
# file (it asks for libzip); find it directly.
find_path(LIB3MF_INCLUDE_DIR lib3mf/Model/COM/NMR_DLLInterfaces.h)
find_library(LIB3MF_LIBRARY NAMES 3MF)
if(LIB3MF_INCLUDE_DIR AND LIB3MF_LIBRARY)
  set(LIB3MF_FOUND TRUE)
endif()
clearfit_require(LIB3MF_FOUND "lib3mf" lib3mf-dev)
# libzip: clearfit checks a 3MF's zip entries (declared sizes against packed bytes) before lib3mf reads it.
if(PkgConfig_FOUND)
  pkg_check_modules(LIBZIP QUIET IMPORTED_TARGET libzip)
endif()
clearfit_require(LIBZIP_FOUND "libzip" libzip-dev)
if(NOT TARGET clearfit_dep::lib3mf)
  add_library(clearfit_dep::lib3mf UNKNOWN IMPORTED)
  set_target_properties(clearfit_dep::lib3mf PROPERTIES
    IMPORTED_LOCATION ${LIB3MF_LIBRARY}
    INTERFACE_INCLUDE_DIRECTORIES "${LIB3MF_INCLUDE_DIR}/lib3mf")
endif()

# mrcal 2.2 ships neither a CMake config nor a pkg-config file.
find_path(MRCAL_INCLUDE_DIR mrcal/mrcal.h)
find_library(MRCAL_LIBRARY NAMES mrcal)
if(MRCAL_INCLUDE_DIR AND MRCAL_LIBRARY)
  set(MRCAL_FOUND TRUE)
endif()
clearfit_require(MRCAL_FOUND "mrcal" libmrcal-dev)
if(NOT TARGET clearfit_dep::mrcal)
  add_library(clearfit_dep::mrcal UNKNOWN IMPORTED)
  set_target_properties(clearfit_dep::mrcal PROPERTIES
    IMPORTED_LOCATION ${MRCAL_LIBRARY}
    INTERFACE_INCLUDE_DIRECTORIES ${MRCAL_INCLUDE_DIR})
endif()

if(CLEARFIT_BUILD_TESTS)
  find_package(GTest QUIET)
  clearfit_require(GTest_FOUND "GoogleTest" "libgtest-dev libgmock-dev")
endif()
if(CLEARFIT_BUILD_BENCHMARKS)
  find_package(benchmark QUIET)
  clearfit_require(benchmark_FOUND "Google Benchmark" libbenchmark-dev)
endif()

# GetFEM (C++ finite elements; the study's layered fingertip model). No CMake or pkg-config file ships with it.
find_library(GETFEM_LIBRARY getfem)
find_path(GETFEM_INCLUDE_DIR getfem/getfem_models.h)
if(GETFEM_LIBRARY AND GETFEM_INCLUDE_DIR)
  set(GETFEM_FOUND TRUE)
endif()
clearfit_require(GETFEM_FOUND "GetFEM" libgetfem-dev)
add_library(clearfit_getfem INTERFACE)
target_include_directories(clearfit_getfem SYSTEM INTERFACE ${GETFEM_INCLUDE_DIR})
target_link_libraries(clearfit_getfem INTERFACE ${GETFEM_LIBRARY})
