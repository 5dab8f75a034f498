# lmf-types.jar: the LCM message types of lcmtypes/ for the Java LCM tools
# (lcm-spy decodes lmf's channels with it; scripts/spy.sh). Built when a JDK
# (javac, jar) and LCM's Java library (lcm.jar) are there; otherwise the
# configure step says which is missing and nothing else changes.
# Included by lcmtypes/CMakeLists.txt with LMF_LCM_TYPES set.
find_package(Java 1.8 COMPONENTS Development QUIET)
find_file(LMF_LCM_JAR lcm.jar PATHS /usr/share/java /usr/local/share/java
          DOC "LCM's Java library (Debian: liblcm-java)")
if(NOT Java_JAVAC_EXECUTABLE OR NOT Java_JAR_EXECUTABLE)
  message(STATUS "lmf-types.jar: not built: no JDK found (javac and jar; Debian: default-jdk-headless)")
  return()
endif()
if(NOT LMF_LCM_JAR)
  message(STATUS "lmf-types.jar: not built: no lcm.jar found (Debian: liblcm-java)")
  return()
endif()

set(java_dir ${CMAKE_CURRENT_BINARY_DIR}/java)
set(LMF_TYPES_JAR ${CMAKE_CURRENT_BINARY_DIR}/lmf-types.jar)
set(lcm_sources)
set(java_sources)
foreach(file ${LMF_LCM_TYPES})
  string(REGEX REPLACE "^lmf_(.*)\\.lcm$" "\\1" type ${file})
  list(APPEND lcm_sources ${CMAKE_CURRENT_SOURCE_DIR}/${file})
  list(APPEND java_sources ${java_dir}/src/lmf/${type}.java)
endforeach()
add_custom_command(
  OUTPUT ${LMF_TYPES_JAR}
  COMMAND ${CMAKE_COMMAND} -E rm -rf ${java_dir}
  COMMAND ${CMAKE_COMMAND} -E make_directory ${java_dir}/src ${java_dir}/classes
  COMMAND ${LCM_GEN_EXECUTABLE} -j --jpath ${java_dir}/src ${lcm_sources}
  COMMAND ${Java_JAVAC_EXECUTABLE} -nowarn -encoding UTF-8 -cp ${LMF_LCM_JAR} -d ${java_dir}/classes ${java_sources}
  COMMAND ${Java_JAR_EXECUTABLE} cf ${LMF_TYPES_JAR} -C ${java_dir}/classes .
  DEPENDS ${lcm_sources}
  COMMENT "lcm-gen --java, javac, jar: lmf-types.jar"
  VERBATIM)
add_custom_target(lmf_types_jar ALL DEPENDS ${LMF_TYPES_JAR})
set(LMF_TYPES_JAR ${LMF_TYPES_JAR} PARENT_SCOPE)
set(LMF_LCM_TYPES ${LMF_LCM_TYPES} PARENT_SCOPE)  # for tests/lcm_java
message(STATUS "lmf-types.jar: built with ${Java_JAVAC_EXECUTABLE} against ${LMF_LCM_JAR}")
