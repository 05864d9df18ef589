# The order the dynamic loader searches the shared libraries in.
#
# Debian's OpenImageIO pulls in about 250 shared libraries (OpenVDB, GDAL through OpenCV, DCMTK,
# FFmpeg...). Every symbol a library binds at start-up is looked up in the global scope, library
# by library in load order, until one defines it; most of a process's start-up went into those
# searches (perf: 69 % of an empty program linked to OpenImageIO in the loader's do_lookup_x and
# _dl_lookup_symbol_x). The load order is breadth first from the executable's own list of needed
# libraries, so the executable can put first the libraries most lookups end in: OpenVDB alone
# binds 57,000 of its own symbols, and it sits deep in OpenImageIO's tree.
#
# posthaste_load_order() links a probe against the same libraries as posthaste, runs it once
# with the loader's LD_DEBUG=bindings, counts the bindings each library receives, and returns
# those libraries by that count, most first. posthaste_fast_load(target) puts them at the head
# of the target's needed list. Nothing is loaded that was not loaded before: the list is only
# the libraries the probe loaded anyway, in another order. Where a symbol is defined by more
# than one library, the first in the new order wins; measured on Debian bookworm, the only such
# symbols are C++ template instantiations (the same code from the same headers), glibc's
# aliases between libc and libm, and strlcat (libbsd's or NetCDF's copy).
#
# Off for the sanitizer builds (the sanitizer runtime must come first), where the probe cannot
# run (not Linux with glibc, cross-compiling), or with -DPOSTHASTE_LOAD_ORDER=OFF.

option(POSTHASTE_LOAD_ORDER "Order the needed libraries by the loader's lookups (start-up time)"
       ON)
# What the probe links: the shared libraries the floors link (CMakeLists.txt).
set(POSTHASTE_LOAD_ORDER_PROBE_LIBS OpenImageIO::OpenImageIO OpenEXR::OpenEXR PkgConfig::OCIO
    TBB::tbb hwy::hwy PkgConfig::FFTW3F)

# A key for a measured order: what the probe links and the modification times of the order's
# libraries, or "" when one is gone (an upgrade that renamed it).
function(posthaste_load_order_key libs out)
  set(stamps "${POSTHASTE_LOAD_ORDER_PROBE_LIBS};")
  foreach(lib IN LISTS libs)
    if(NOT EXISTS "${lib}")
      set(${out} "" PARENT_SCOPE)
      return()
    endif()
    file(TIMESTAMP "${lib}" stamp "%s" UTC)
    string(APPEND stamps "${lib}=${stamp};")
  endforeach()
  string(MD5 key "${stamps}")
  set(${out} "${key}" PARENT_SCOPE)
endfunction()

function(posthaste_load_order out)
  set(${out} "" PARENT_SCOPE)
  if(NOT POSTHASTE_LOAD_ORDER OR POSTHASTE_SANITIZE OR POSTHASTE_FUZZ OR CMAKE_CROSSCOMPILING
     OR NOT CMAKE_SYSTEM_NAME STREQUAL "Linux")
    return()
  endif()
  # The probe takes about 5 s; a re-configure keeps the last order while every one of its
  # libraries is still there, unchanged (any library OpenImageIO gains changes its own file).
  if(POSTHASTE_LOAD_ORDER_MEASURED)
    posthaste_load_order_key("${POSTHASTE_LOAD_ORDER_MEASURED}" key)
    if(key AND key STREQUAL POSTHASTE_LOAD_ORDER_MEASURED_KEY)
      set(${out} "${POSTHASTE_LOAD_ORDER_MEASURED}" PARENT_SCOPE)
      return()
    endif()
  endif()
  set(dir ${PROJECT_BINARY_DIR}/load_order)
  file(WRITE ${dir}/probe.cpp [=[
#include <OpenColorIO/OpenColorIO.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenImageIO/imageio.h>
int main(int argc, char **)
{
    // Referenced, never run: each library stays needed.
    if (argc > 100) {
        Imf::Header header;
        return OIIO::openimageio_version() + int(OCIO_NAMESPACE::GetVersionHex()) +
               header.dataWindow().max.x;
    }
    return 0;
}
]=])
  try_compile(built ${dir}/build
    SOURCES ${dir}/probe.cpp
    CXX_STANDARD 20
    LINK_LIBRARIES ${POSTHASTE_LOAD_ORDER_PROBE_LIBS}
    LINK_OPTIONS -Wl,--no-as-needed
    COPY_FILE ${dir}/probe
    OUTPUT_VARIABLE log)
  if(NOT built)
    message(STATUS "posthaste: load order left to the linker (the probe did not build)")
    return()
  endif()
  # One line per library: its binding count and path, most bound first.
  execute_process(
    COMMAND sh -c "LD_DEBUG=bindings '${dir}/probe' 2>&1 >/dev/null \
      | sed -n 's/.* to \\(\\/[^ ]*\\) \\[0\\].*/\\1/p' | sort | uniq -c | sort -k1,1nr -k2"
    RESULT_VARIABLE rc
    OUTPUT_VARIABLE counted
    OUTPUT_STRIP_TRAILING_WHITESPACE)
  if(NOT rc EQUAL 0 OR counted STREQUAL "")
    message(STATUS "posthaste: load order left to the linker (LD_DEBUG gave nothing)")
    return()
  endif()
  string(REPLACE "\n" ";" lines "${counted}")
  set(libs "")
  foreach(line IN LISTS lines)
    string(REGEX REPLACE "^ *[0-9]+ +" "" lib "${line}")
    get_filename_component(name "${lib}" NAME)
    # The loader and the probe itself are not libraries to link.
    if(name MATCHES "^ld-linux" OR name STREQUAL "probe" OR NOT EXISTS "${lib}")
      continue()
    endif()
    list(APPEND libs "${lib}")
  endforeach()
  list(LENGTH libs count)
  message(STATUS "posthaste: load order of ${count} libraries from the loader's lookups")
  posthaste_load_order_key("${libs}" key)
  set(POSTHASTE_LOAD_ORDER_MEASURED "${libs}" CACHE INTERNAL "The measured load order")
  set(POSTHASTE_LOAD_ORDER_MEASURED_KEY "${key}" CACHE INTERNAL "Its libraries' times")
  set(${out} "${libs}" PARENT_SCOPE)
endfunction()

posthaste_load_order(POSTHASTE_LOAD_ORDER_LIBS)

function(posthaste_fast_load target)
  if(POSTHASTE_LOAD_ORDER_LIBS)
    target_link_options(${target} PRIVATE "LINKER:--push-state,--no-as-needed"
                        ${POSTHASTE_LOAD_ORDER_LIBS} "LINKER:--pop-state")
  endif()
endfunction()
