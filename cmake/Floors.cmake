# The floors: one static library per source folder, each naming the floors below it that it may
# use. Two checks keep them honest:
#  - every build runs cmake/check_floors.cmake, which fails on a file that includes a header of a
#    floor its own floor does not name (an include upward or sideways);
#  - with the tests, each floor is linked alone and whole (every object of it) against only the
#    floors it names, so a call into a floor it does not name (a declaration reaching up, say)
#    is an undefined symbol at link time.

# posthaste_floor(NAME DIR folder [FLOORS floor...] [LIBS target...] [EXTRA source...])
# A static library posthaste_NAME of the *.cpp under DIR (its family folders too: src/shading/dof/)
# and EXTRA, linking the named floors and LIBS.
function(posthaste_floor name)
  cmake_parse_arguments(F "" "DIR" "FLOORS;LIBS;EXTRA" ${ARGN})
  file(GLOB_RECURSE _sources CONFIGURE_DEPENDS ${PROJECT_SOURCE_DIR}/${F_DIR}/*.cpp)
  add_library(posthaste_${name} STATIC ${_sources} ${F_EXTRA})
  target_compile_options(posthaste_${name} PRIVATE ${POSTHASTE_WARNINGS})
  set(_deps "")
  foreach(_floor IN LISTS F_FLOORS)
    list(APPEND _deps posthaste_${_floor})
  endforeach()
  target_link_libraries(posthaste_${name} PUBLIC ${_deps} ${F_LIBS})
  posthaste_floor_rule(${name} DIR ${F_DIR} FLOORS ${F_FLOORS})
  set_property(GLOBAL APPEND PROPERTY POSTHASTE_FLOOR_LIBRARIES ${name})
endfunction()

# posthaste_floor_rule(NAME DIR folder [FLOORS floor...]): the include rule alone, for a folder
# that is not a library of its own (the CLI's).
function(posthaste_floor_rule name)
  cmake_parse_arguments(F "" "DIR" "FLOORS" ${ARGN})
  string(REPLACE ";" "," _uses "${F_FLOORS}")
  set_property(GLOBAL APPEND PROPERTY POSTHASTE_FLOOR_RULES "${name}|${F_DIR}|${_uses}")
endfunction()

# After every floor is declared: the include check as a build step, and the link checks.
function(posthaste_check_floors)
  get_property(_rules GLOBAL PROPERTY POSTHASTE_FLOOR_RULES)
  set(_files "")
  set(_text "")
  foreach(_rule IN LISTS _rules)
    string(REPLACE "|" ";" _parts "${_rule}")
    list(GET _parts 1 _dir)
    file(GLOB_RECURSE _f CONFIGURE_DEPENDS ${PROJECT_SOURCE_DIR}/${_dir}/*.cpp
         ${PROJECT_SOURCE_DIR}/${_dir}/*.h)
    list(APPEND _files ${_f})
    string(APPEND _text "${_rule}\n")
  endforeach()
  set(_rules_file ${PROJECT_BINARY_DIR}/floors.txt)
  file(WRITE ${_rules_file}.new "${_text}")
  file(COPY_FILE ${_rules_file}.new ${_rules_file} ONLY_IF_DIFFERENT)
  set(_stamp ${PROJECT_BINARY_DIR}/floors.stamp)
  add_custom_command(
    OUTPUT ${_stamp}
    COMMAND ${CMAKE_COMMAND} -DRULES=${_rules_file} -DSOURCE=${PROJECT_SOURCE_DIR}
            -DSTAMP=${_stamp} -P ${PROJECT_SOURCE_DIR}/cmake/check_floors.cmake
    DEPENDS ${_files} ${_rules_file} ${PROJECT_SOURCE_DIR}/cmake/check_floors.cmake
    COMMENT "Checking that every include stays on its floor or below"
    VERBATIM)
  add_custom_target(posthaste_floors ALL DEPENDS ${_stamp})

  if(POSTHASTE_TESTS)
    get_property(_libraries GLOBAL PROPERTY POSTHASTE_FLOOR_LIBRARIES)
    foreach(_name IN LISTS _libraries)
      add_executable(posthaste_floor_link_${_name} ${PROJECT_SOURCE_DIR}/cmake/floor_link.cpp)
      target_link_libraries(posthaste_floor_link_${_name} PRIVATE
                            "$<LINK_LIBRARY:WHOLE_ARCHIVE,posthaste_${_name}>")
    endforeach()
  endif()
endfunction()
