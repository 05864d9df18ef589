# Every dependency comes from a Debian bookworm package (README.md lists them). Two of Debian's
# CMake configs are broken; the work-arounds are here (shared/DEPENDENCIES.md).

find_package(OpenImageIO CONFIG REQUIRED)
find_package(OpenEXR CONFIG REQUIRED)
find_package(Imath CONFIG REQUIRED)
find_package(glm CONFIG REQUIRED)
find_package(nlohmann_json CONFIG REQUIRED)
find_package(CLI11 CONFIG REQUIRED)
find_package(TBB CONFIG REQUIRED)
find_package(Threads REQUIRED)

# OpenImageIO's imported target names /usr/include/opencv4, which exists only when
# libopencv-core-dev is installed; drop include directories that do not exist.
get_target_property(_oiio_includes OpenImageIO::OpenImageIO INTERFACE_INCLUDE_DIRECTORIES)
if(_oiio_includes)
  set(_kept "")
  foreach(_dir IN LISTS _oiio_includes)
    if(EXISTS "${_dir}" OR _dir MATCHES "^\\$<")
      list(APPEND _kept "${_dir}")
    endif()
  endforeach()
  set_target_properties(OpenImageIO::OpenImageIO PROPERTIES INTERFACE_INCLUDE_DIRECTORIES "${_kept}")
endif()

# Debian's OpenColorIO config sets a bogus include path: use pkg-config instead.
find_package(PkgConfig REQUIRED)
pkg_check_modules(OCIO REQUIRED IMPORTED_TARGET OpenColorIO>=2.1)
if(NOT TARGET OpenColorIO::OpenColorIO)
  add_library(OpenColorIO::OpenColorIO ALIAS PkgConfig::OCIO)
endif()

# Google Highway: portable SIMD, one kernel source compiled per target with run-time dispatch.
find_package(hwy CONFIG REQUIRED)

# FFTW 3, single precision (bloom's exact convolution, the lens's diffraction pattern).
pkg_check_modules(FFTW3F REQUIRED IMPORTED_TARGET fftw3f>=3.3)

if(POSTHASTE_TESTS)
  find_package(GTest CONFIG REQUIRED)
endif()
if(POSTHASTE_BENCHMARKS)
  find_package(benchmark CONFIG REQUIRED)
endif()
