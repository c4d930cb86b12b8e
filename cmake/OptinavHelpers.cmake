# optinav_add_library(NAME layer SRCS ... PUBLIC_DEPS ... PRIVATE_DEPS ...): one library per layer
# folder. PUBLIC_DEPS are the libraries the layer's headers include (users need their include
# directories too); PRIVATE_DEPS are used by the .cc files only. Static libraries still pass
# private dependencies on to the link line, so only the include directories stop propagating.
# scripts/check_layering.py checks that every layer a header includes is reachable through
# PUBLIC_DEPS. DEPS is the older spelling of PUBLIC_DEPS.
function(optinav_add_library)
  cmake_parse_arguments(ARG "" "NAME" "SRCS;DEPS;PUBLIC_DEPS;PRIVATE_DEPS" ${ARGN})
  add_library(optinav_${ARG_NAME} STATIC ${ARG_SRCS})
  target_include_directories(optinav_${ARG_NAME} PUBLIC ${CMAKE_SOURCE_DIR}/src)
  target_link_libraries(optinav_${ARG_NAME} PUBLIC ${ARG_DEPS} ${ARG_PUBLIC_DEPS}
                        PRIVATE ${ARG_PRIVATE_DEPS})
  # The Python module links the libraries into a shared object. Without semantic interposition
  # (no other library replaces ours at load time) -fPIC code inlines and calls as -fPIE code does.
  if(OPTINAV_WITH_PYTHON)
    set_target_properties(optinav_${ARG_NAME} PROPERTIES POSITION_INDEPENDENT_CODE ON)
    if(CMAKE_CXX_COMPILER_ID STREQUAL "GNU")
      target_compile_options(optinav_${ARG_NAME} PRIVATE -fno-semantic-interposition)
    endif()
  endif()
endfunction()

# optinav_add_test(NAME name LAYER layer SRCS ... DEPS ...): registers <layer>/<name> with CTest.
function(optinav_add_test)
  cmake_parse_arguments(ARG "" "NAME;LAYER" "SRCS;DEPS" ${ARGN})
  if(NOT OPTINAV_BUILD_TESTS)
    return()
  endif()
  set(target test_${ARG_LAYER}_${ARG_NAME})
  add_executable(${target} ${ARG_SRCS})
  target_link_libraries(${target} PRIVATE optinav_test_main ${ARG_DEPS})
  add_test(NAME ${ARG_LAYER}/${ARG_NAME} COMMAND ${target})
  set_tests_properties(${ARG_LAYER}/${ARG_NAME} PROPERTIES TIMEOUT 600)
endfunction()
