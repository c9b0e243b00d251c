# omnipose_lcm_python(TARGET PPATH OUT_VAR): lcm-gen's Python modules of lcm_types/*.lcm, one
# per type and the package's __init__.py (which imports them), written to PPATH/omnipose/ by
# the target TARGET (built by default). OUT_VAR receives the files, __init__.py first. The
# modules need only `struct`, not the LCM Python module. Used for the .deb
# (lcm_types/CMakeLists.txt) and for the Python package (src/python/CMakeLists.txt).
function(omnipose_lcm_python target ppath out_var)
  find_program(OMNIPOSE_LCM_GEN lcm-gen REQUIRED)  # Debian: liblcm-bin
  file(GLOB lcm_files CONFIGURE_DEPENDS ${CMAKE_SOURCE_DIR}/lcm_types/*.lcm)
  list(SORT lcm_files)
  set(files ${ppath}/omnipose/__init__.py)
  foreach(lcm_file IN LISTS lcm_files)
    get_filename_component(type_name ${lcm_file} NAME_WE)
    list(APPEND files ${ppath}/omnipose/${type_name}.py)
  endforeach()
  # lcm-gen adds imports to an existing __init__.py: start from none, so a removed type goes.
  add_custom_command(
    OUTPUT ${files}
    COMMAND ${CMAKE_COMMAND} -E rm -rf ${ppath}/omnipose
    COMMAND ${CMAKE_COMMAND} -E make_directory ${ppath}
    COMMAND ${OMNIPOSE_LCM_GEN} --python --ppath ${ppath} ${lcm_files}
    DEPENDS ${lcm_files}
    COMMENT "lcm-gen: Python types of ${CMAKE_SOURCE_DIR}/lcm_types/*.lcm"
    VERBATIM)
  add_custom_target(${target} ALL DEPENDS ${files})
  set(${out_var} ${files} PARENT_SCOPE)
endfunction()
