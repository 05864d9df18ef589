# The source tree's floors that a compiler does not check (docs/ARCHITECTURE.md): no source file
# under src/ or nodes/ over 600 lines (split by responsibility instead), and no hand-written AVX
# intrinsics (_mm256_*) outside the SIMD layer (src/core/hwy_math-inl.h); kernels are written
# once over Highway. Run: cmake -DSOURCE_DIR=<repository root> -P source_floors.cmake
file(GLOB_RECURSE _files RELATIVE ${SOURCE_DIR}
     ${SOURCE_DIR}/src/*.cpp ${SOURCE_DIR}/src/*.h ${SOURCE_DIR}/src/*.in
     ${SOURCE_DIR}/nodes/*.cpp ${SOURCE_DIR}/nodes/*.h)
set(_problems "")
foreach(_f IN LISTS _files)
  file(READ ${SOURCE_DIR}/${_f} _text)
  # Lines: the newlines (MATCHALL's list has one entry per match).
  string(REGEX MATCHALL "\n" _newlines "${_text}")
  list(LENGTH _newlines _n)
  if(_n GREATER 600)
    string(APPEND _problems "${_f}: ${_n} lines (at most 600)\n")
  endif()
  if(NOT _f STREQUAL "src/core/hwy_math-inl.h")
    string(FIND "${_text}" "_mm256" _pos)
    if(NOT _pos EQUAL -1)
      string(APPEND _problems "${_f}: AVX intrinsics (_mm256) outside src/core/hwy_math-inl.h\n")
    endif()
  endif()
endforeach()
list(LENGTH _files _count)
if(_count LESS 100)
  message(FATAL_ERROR "only ${_count} source files found under ${SOURCE_DIR}: wrong SOURCE_DIR?")
endif()
if(_problems)
  message(FATAL_ERROR "source floors:\n${_problems}")
endif()
message(STATUS "${_count} source files within the floors")
