# The message list (messages/include/exodaq/messages/message_list.def) as
# CMake reads it: lcmtypes/ takes lcm-gen's input from it, tools/python the
# Python names module. The configuration fails on any line that is neither a
# comment nor one entry of the documented shape, on a name given twice, and
# when the list and the .lcm files differ.
#
#   exodaq_message_list(<var>)
# sets, in the caller's scope:
#   <var>                     the types in list order (joint_state_t;palm_pose_t;...)
#   <var>_<type>_KIND         kJointState
#   <var>_<type>_CHANNEL      EXO_JOINT_STATE
#   <var>_<type>_PER_CYCLE    true or false
#   <var>_<type>_ALIASES      the aliases as a CMake list (joint;joints), maybe empty
# and makes a change of the list re-run the configuration.
#
#   exodaq_message_lcm_files(<var> <types> <dir>)
# sets <var> to <dir>/<type>.lcm for each of <types>, failing unless those are
# exactly the .lcm files of <dir> and each declares `struct <type>`.
#
# Both also run in script mode (cmake -P), reading ${EXODAQ_MESSAGE_LIST}:
# tests/clients/message_list_check.cmake.
set(EXODAQ_MESSAGE_LIST ${CMAKE_CURRENT_LIST_DIR}/../messages/include/exodaq/messages/message_list.def)
cmake_path(NORMAL_PATH EXODAQ_MESSAGE_LIST)

function(exodaq_message_list var)
  set(def ${EXODAQ_MESSAGE_LIST})
  if(NOT CMAKE_SCRIPT_MODE_FILE)
    set_property(DIRECTORY APPEND PROPERTY CMAKE_CONFIGURE_DEPENDS ${def})
  endif()
  file(STRINGS ${def} lines)
  set(entry "^EXODAQ_MESSAGE\\((k[A-Z][A-Za-z0-9]*), ([a-z][a-z0-9_]*_t), \"([A-Z][A-Z0-9_]*)\", (true|false), \"([a-z0-9_ ]*)\"\\)$")
  set(types "")
  set(seen "")
  foreach(line IN LISTS lines)
    if(line MATCHES "^[ \t]*(//.*)?$")
      continue()
    endif()
    if(NOT line MATCHES "${entry}")
      message(FATAL_ERROR "${def}: not a comment and not an entry "
        "EXODAQ_MESSAGE(kName, name_t, \"CHANNEL\", true|false, \"aliases\"): ${line}")
    endif()
    set(kind ${CMAKE_MATCH_1})
    set(type ${CMAKE_MATCH_2})
    set(channel ${CMAKE_MATCH_3})
    set(per_cycle ${CMAKE_MATCH_4})
    string(REPLACE " " ";" aliases "${CMAKE_MATCH_5}")
    string(REGEX REPLACE "_t$" "" short ${type})
    # Every name a user may type for a kind (messages::parse_kind) is one kind's only.
    foreach(name ${kind} ${type} ${short} ${channel} ${aliases})
      string(TOUPPER ${name} upper)
      if(upper IN_LIST seen)
        message(FATAL_ERROR "${def}: '${name}' named twice (in: ${line})")
      endif()
      list(APPEND seen ${upper})
    endforeach()
    list(APPEND types ${type})
    set(${var}_${type}_KIND ${kind} PARENT_SCOPE)
    set(${var}_${type}_CHANNEL ${channel} PARENT_SCOPE)
    set(${var}_${type}_PER_CYCLE ${per_cycle} PARENT_SCOPE)
    set(${var}_${type}_ALIASES "${aliases}" PARENT_SCOPE)
  endforeach()
  if(NOT types)
    message(FATAL_ERROR "${def}: no EXODAQ_MESSAGE entry")
  endif()
  set(${var} ${types} PARENT_SCOPE)
endfunction()

function(exodaq_message_lcm_files var types dir)
  if(CMAKE_SCRIPT_MODE_FILE)
    file(GLOB present RELATIVE ${dir} ${dir}/*.lcm)
  else()
    file(GLOB present CONFIGURE_DEPENDS RELATIVE ${dir} ${dir}/*.lcm)
  endif()
  set(files "")
  foreach(t ${types})
    set(f ${dir}/${t}.lcm)
    if(NOT EXISTS ${f})
      message(FATAL_ERROR "${EXODAQ_MESSAGE_LIST} lists ${t}, but ${f} does not exist")
    endif()
    file(STRINGS ${f} struct REGEX "^[ \t]*struct[ \t]")
    if(NOT struct MATCHES "^[ \t]*struct[ \t]+${t}([ \t{]|$)")
      message(FATAL_ERROR "${f}: declares '${struct}', not struct ${t}")
    endif()
    list(REMOVE_ITEM present ${t}.lcm)
    list(APPEND files ${f})
  endforeach()
  if(present)
    message(FATAL_ERROR "${dir} holds ${present}, which ${EXODAQ_MESSAGE_LIST} does not list: "
      "add its line there (or remove the file)")
  endif()
  set(${var} ${files} PARENT_SCOPE)
endfunction()
