# The configure-time checks of the message list (cmake/ExodaqMessageList.cmake):
# the project's own list and .lcm files are accepted, in list order; a list
# and a .lcm set that disagree, a malformed line, a name given twice and a
# file whose struct is misnamed are each refused with a message that names
# the cause.
#   cmake -DSOURCE_DIR=<project> -DWORK=<scratch dir> -P message_list_check.cmake
# With -DCASE_LIST=<file> -DCASE_LCM=<dir> it checks one case and prints the
# types (what the driver runs as a child).
cmake_minimum_required(VERSION 3.25)
if(DEFINED CASE_LIST)
  include(${SOURCE_DIR}/cmake/ExodaqMessageList.cmake)
  set(EXODAQ_MESSAGE_LIST ${CASE_LIST})
  exodaq_message_list(types)
  exodaq_message_lcm_files(files "${types}" ${CASE_LCM})
  message(STATUS "types: ${types}")
  return()
endif()

set(list_file ${SOURCE_DIR}/messages/include/exodaq/messages/message_list.def)
set(lcm_dir ${SOURCE_DIR}/lcmtypes/exodaq)

# Runs one case; `expect` is "ok: <types>" or a text the error must hold.
function(check name case_list case_lcm expect)
  execute_process(COMMAND ${CMAKE_COMMAND} -DSOURCE_DIR=${SOURCE_DIR} -DCASE_LIST=${case_list}
                          -DCASE_LCM=${case_lcm} -P ${CMAKE_CURRENT_LIST_FILE}
                  RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  string(REPLACE "\n" " " all "${out} ${err}")
  string(REGEX REPLACE "  +" " " all "${all}")
  if(expect MATCHES "^ok: (.*)$")
    set(want "types: ${CMAKE_MATCH_1}")
    if(NOT rc EQUAL 0 OR NOT all MATCHES "${want}")
      message(SEND_ERROR "${name}: expected success with '${want}', got rc ${rc}: ${all}")
    endif()
  elseif(rc EQUAL 0 OR NOT all MATCHES "${expect}")
    message(SEND_ERROR "${name}: expected a failure naming '${expect}', got rc ${rc}: ${all}")
  else()
    message(STATUS "${name}: refused as expected")
  endif()
endfunction()

# A copy of the real .lcm files in `dir`.
function(lcm_copy dir)
  file(REMOVE_RECURSE ${dir})
  file(GLOB lcm ${lcm_dir}/*.lcm)
  file(COPY ${lcm} DESTINATION ${dir})
endfunction()

file(READ ${list_file} real)
set(palm_velocity_line
  "EXODAQ_MESSAGE(kPalmVelocity, palm_velocity_t, \"EXO_PALM_VELOCITY\", true, \"\")\n")
set(palm_velocity_lcm "package exodaq;\nstruct palm_velocity_t\n{\n  int64_t utime;\n}\n")

check(real_list ${list_file} ${lcm_dir}
  "ok: joint_state_t;palm_pose_t;encoder_raw_t;status_t;homing_t;source_status_t ")

# A .lcm file the list does not name.
lcm_copy(${WORK}/extra_lcm)
file(WRITE ${WORK}/extra_lcm/palm_velocity_t.lcm "${palm_velocity_lcm}")
check(lcm_not_listed ${list_file} ${WORK}/extra_lcm "holds palm_velocity_t.lcm, which .* does not list")

# A line for a type without its .lcm file.
file(WRITE ${WORK}/extra_line.def "${real}${palm_velocity_line}")
check(listed_without_lcm ${WORK}/extra_line.def ${lcm_dir} "lists palm_velocity_t, but .* does not exist")

# Both: accepted, the new type last.
check(both ${WORK}/extra_line.def ${WORK}/extra_lcm
  "ok: joint_state_t;palm_pose_t;encoder_raw_t;status_t;homing_t;source_status_t;palm_velocity_t")

# A line of another shape (no per_cycle).
file(WRITE ${WORK}/malformed.def
  "${real}EXODAQ_MESSAGE(kPalmVelocity, palm_velocity_t, \"EXO_PALM_VELOCITY\", \"\")\n")
check(malformed_line ${WORK}/malformed.def ${WORK}/extra_lcm "not a comment and not an entry")

# An alias another kind already has.
file(WRITE ${WORK}/twice.def
  "${real}EXODAQ_MESSAGE(kPalmVelocity, palm_velocity_t, \"EXO_PALM_VELOCITY\", true, \"raw\")\n")
check(alias_twice ${WORK}/twice.def ${WORK}/extra_lcm "'raw' named twice")

# A file whose struct is not named after it.
lcm_copy(${WORK}/misnamed)
file(WRITE ${WORK}/misnamed/palm_velocity_t.lcm
  "package exodaq;\nstruct palm_velocity\n{\n  int64_t utime;\n}\n")
check(misnamed_struct ${WORK}/extra_line.def ${WORK}/misnamed "not struct palm_velocity_t")
