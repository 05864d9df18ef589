# The Python module `posthaste` (src/python, docs/PYTHON.md): built into build/python beside its
# type stubs (posthaste.pyi, written from the node catalog by the module itself after each link),
# so `PYTHONPATH=build/python python3` imports it; `cmake --install` puts both into the
# interpreter's site folder under CMAKE_INSTALL_PREFIX (POSTHASTE_PYTHON_INSTALL_DIR overrides).

file(GLOB POSTHASTE_PYTHON_SOURCES CONFIGURE_DEPENDS ${PROJECT_SOURCE_DIR}/src/python/*.cpp)
# NO_EXTRAS: no link-time optimisation (the floors are built without it) and no stripping.
pybind11_add_module(posthaste_python MODULE NO_EXTRAS ${POSTHASTE_PYTHON_SOURCES})
set(POSTHASTE_PYTHON_DIR ${PROJECT_BINARY_DIR}/python)
set_target_properties(posthaste_python PROPERTIES OUTPUT_NAME posthaste
                      LIBRARY_OUTPUT_DIRECTORY ${POSTHASTE_PYTHON_DIR}
                      CXX_VISIBILITY_PRESET hidden VISIBILITY_INLINES_HIDDEN ON)
target_compile_options(posthaste_python PRIVATE ${POSTHASTE_WARNINGS})
target_link_libraries(posthaste_python PRIVATE posthaste_nodes posthaste_metrics)
# The floors' symbols stay inside the module (no clash with another module in the process, and
# calls between them bind directly instead of through the procedure linkage table).
target_link_options(posthaste_python PRIVATE -Wl,--exclude-libs,ALL)
# Its needed libraries in the loader's best order, as the executables' (cmake/LoadOrder.cmake).
posthaste_fast_load(posthaste_python)
add_custom_command(TARGET posthaste_python POST_BUILD
  COMMAND ${CMAKE_COMMAND} -E env PYTHONPATH=${POSTHASTE_PYTHON_DIR}
          ${Python_EXECUTABLE} -c
          "import posthaste, sys; open(sys.argv[1], 'w').write(posthaste._stub_text())"
          ${POSTHASTE_PYTHON_DIR}/posthaste.pyi
  COMMENT "Writing the Python module's type stubs (posthaste.pyi)"
  VERBATIM)

if(NOT POSTHASTE_PYTHON_INSTALL_DIR)
  # The interpreter's site folder relative to the prefix, so `cmake --install --prefix DIR`
  # puts the module under DIR: lib/python3.X/site-packages, or dist-packages where the
  # interpreter reads those (Debian's, which reads /usr/local/lib/python3.X/dist-packages).
  execute_process(
    COMMAND ${Python_EXECUTABLE} -c
            "import sys, sysconfig; v = 'python%d.%d/dist-packages' % sys.version_info[:2]; p = sysconfig.get_path('platlib', 'posix_prefix', vars={'platbase': '/P', 'base': '/P'})[3:]; print(p.replace('site-packages', 'dist-packages') if any(x.endswith(v) for x in sys.path) else p)"
    OUTPUT_VARIABLE POSTHASTE_PYTHON_INSTALL_DIR OUTPUT_STRIP_TRAILING_WHITESPACE)
endif()
install(TARGETS posthaste_python LIBRARY DESTINATION ${POSTHASTE_PYTHON_INSTALL_DIR})
install(FILES ${POSTHASTE_PYTHON_DIR}/posthaste.pyi DESTINATION ${POSTHASTE_PYTHON_INSTALL_DIR})
