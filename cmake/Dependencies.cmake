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
# zlib: the previews' PNG encoder deflates pieces of a frame in parallel (src/io/png_write.cpp).
find_package(ZLIB REQUIRED)

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

# The Python module: Debian's python3-dev, python3-numpy and pybind11-dev, for Debian's own
# interpreter (/usr/bin/python3, where python3-numpy and python3-pytest live) unless
# Python_EXECUTABLE names another. Without them the module is left out, with a note.
if(POSTHASTE_PYTHON AND (POSTHASTE_SANITIZE OR POSTHASTE_FUZZ))
  set(POSTHASTE_PYTHON OFF)
endif()
if(POSTHASTE_PYTHON)
  if(NOT DEFINED Python_EXECUTABLE AND EXISTS /usr/bin/python3)
    set(Python_EXECUTABLE /usr/bin/python3 CACHE FILEPATH "The Python the module is built for")
  endif()
  find_package(Python 3.9 COMPONENTS Interpreter Development.Module NumPy)
  set(PYBIND11_FINDPYTHON ON)
  find_package(pybind11 2.10 CONFIG QUIET)
  if(NOT Python_FOUND OR NOT Python_NumPy_FOUND OR NOT pybind11_FOUND)
    message(STATUS "posthaste: the Python module is not built (needs python3-dev, "
                   "python3-numpy and pybind11-dev)")
    set(POSTHASTE_PYTHON OFF)
  endif()
endif()
