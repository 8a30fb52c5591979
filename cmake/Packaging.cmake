# Installation of the service files and the Debian package (issue 9, docs/operations.md).
#
# Layout, for CMAKE_INSTALL_PREFIX=/usr (the .deb, and `cmake --install build --prefix /usr`):
#   /usr/bin/exodaqd, exodaq, exodaq-board-sim, lcm-spy-exodaq   (their own directories' rules)
#   /usr/share/exodaq/lcmtypes/                                  (lcmtypes/: .lcm, jar)
#   /usr/lib/python3/dist-packages/exodaq/, exodaq_lcm.py         (tools/python: the Python package)
#   /etc/exodaq/exodaqd.yaml, sim.yaml, vcan.yaml, models/, calibration/, tasks/   (conffiles)
#   /lib/systemd/system/exodaqd.service, exodaqd@.service (the template: one
#     instance per rig, exodaqd@<rig>.service reading /etc/exodaq/<rig>.yaml),
#     exodaq.slice (their slice: memory protection)
#   /usr/lib/sysusers.d/exodaq.conf
#   /usr/share/doc/exodaq/  operations.md, messages.md, ..., examples/80-can0.{network,link}
# Any other prefix P (a staging directory, /usr/local) keeps everything under P:
# P/etc/exodaq, P/lib/systemd/system, P/lib/sysusers.d, and the installed unit's
# ExecStart=/config paths point at P/bin/exodaqd and P/etc/exodaq/exodaqd.yaml, so
# `systemd-analyze verify` can check a staged unit as it is (tests/systemd).
# The decision is taken at install time (CPack installs with prefix /usr whatever
# the build was configured with), hence install(CODE) for these files.

set(EXODAQ_SOURCE_CONFIG_DIR ${PROJECT_SOURCE_DIR}/config)
set(EXODAQ_SOURCE_SYSTEMD_DIR ${PROJECT_SOURCE_DIR}/systemd)
file(GLOB EXODAQ_INSTALL_CONFIGS CONFIGURE_DEPENDS
  ${EXODAQ_SOURCE_CONFIG_DIR}/exodaqd.yaml
  ${EXODAQ_SOURCE_CONFIG_DIR}/sim.yaml
  ${EXODAQ_SOURCE_CONFIG_DIR}/vcan.yaml)
file(GLOB EXODAQ_INSTALL_MODELS CONFIGURE_DEPENDS ${EXODAQ_SOURCE_CONFIG_DIR}/models/*.yaml)
file(GLOB EXODAQ_INSTALL_CALIBRATIONS CONFIGURE_DEPENDS
  ${EXODAQ_SOURCE_CONFIG_DIR}/calibration/*.yaml)
file(GLOB EXODAQ_INSTALL_TASKS CONFIGURE_DEPENDS ${EXODAQ_SOURCE_CONFIG_DIR}/tasks/*.yaml)
file(GLOB EXODAQ_INSTALL_DOCS CONFIGURE_DEPENDS ${PROJECT_SOURCE_DIR}/docs/*.md)
list(SORT EXODAQ_INSTALL_CONFIGS)
list(SORT EXODAQ_INSTALL_MODELS)
list(SORT EXODAQ_INSTALL_CALIBRATIONS)
list(SORT EXODAQ_INSTALL_TASKS)
set_property(DIRECTORY APPEND PROPERTY CMAKE_CONFIGURE_DEPENDS
  ${EXODAQ_SOURCE_SYSTEMD_DIR}/exodaqd.service ${EXODAQ_SOURCE_SYSTEMD_DIR}/exodaq.sysusers
  ${EXODAQ_SOURCE_SYSTEMD_DIR}/exodaq.slice)

# The unit, the sysusers file and /etc/exodaq: places depend on the prefix at install time.
install(CODE "
set(_exodaq_bindir \"${CMAKE_INSTALL_BINDIR}\")
set(_exodaq_configs \"${EXODAQ_INSTALL_CONFIGS}\")
set(_exodaq_models \"${EXODAQ_INSTALL_MODELS}\")
set(_exodaq_calibrations \"${EXODAQ_INSTALL_CALIBRATIONS}\")
set(_exodaq_tasks \"${EXODAQ_INSTALL_TASKS}\")
set(_exodaq_unit_in \"${EXODAQ_SOURCE_SYSTEMD_DIR}/exodaqd.service\")
set(_exodaq_sysusers \"${EXODAQ_SOURCE_SYSTEMD_DIR}/exodaq.sysusers\")
set(_exodaq_slice \"${EXODAQ_SOURCE_SYSTEMD_DIR}/exodaq.slice\")
set(_exodaq_gen \"${CMAKE_BINARY_DIR}/install-gen\")
")
install(CODE [==[
if(CMAKE_INSTALL_PREFIX STREQUAL "/usr")
  set(_exodaq_etc "/etc/exodaq")
  set(_exodaq_unitdir "/lib/systemd/system")
  set(_exodaq_sysusersdir "/usr/lib/sysusers.d")
else()
  set(_exodaq_etc "${CMAKE_INSTALL_PREFIX}/etc/exodaq")
  set(_exodaq_unitdir "${CMAKE_INSTALL_PREFIX}/lib/systemd/system")
  set(_exodaq_sysusersdir "${CMAKE_INSTALL_PREFIX}/lib/sysusers.d")
endif()
# The unit as written in systemd/, and the per-rig template made from it (one
# home for the unit's settings): the same unit but for its config,
# /etc/exodaq/%i.yaml, and its description; then both with their paths moved
# to this prefix.
file(READ "${_exodaq_unit_in}" _exodaq_unit)
string(REPLACE "/etc/exodaq/exodaqd.yaml" "/etc/exodaq/%i.yaml" _exodaq_template "${_exodaq_unit}")
string(REPLACE "Description=exodaq encoder acquisition service ("
  "Description=exodaq encoder acquisition service, rig %i (" _exodaq_template "${_exodaq_template}")
string(REGEX REPLACE "^# exodaqd: [^\n]*\n" "# exodaqd@<rig>.service: exodaqd for one of several rigs on this host, with
# /etc/exodaq/<rig>.yaml (its own lcm.prefix, rig name and CAN board; docs/operations.md
# \"Several rigs\"). Made at install from systemd/exodaqd.service (cmake/Packaging.cmake).
" _exodaq_template "${_exodaq_template}")
# One generated copy per destination: installs into several stages may run at once.
string(MD5 _exodaq_key "$ENV{DESTDIR}|${CMAKE_INSTALL_PREFIX}")
file(MAKE_DIRECTORY "${_exodaq_gen}/${_exodaq_key}")
foreach(_exodaq_pair "exodaqd.service;_exodaq_unit" "exodaqd@.service;_exodaq_template")
  list(GET _exodaq_pair 0 _exodaq_name)
  list(GET _exodaq_pair 1 _exodaq_var)
  set(_exodaq_text "${${_exodaq_var}}")
  string(REPLACE "/usr/bin/exodaqd" "${CMAKE_INSTALL_PREFIX}/${_exodaq_bindir}/exodaqd"
    _exodaq_text "${_exodaq_text}")
  string(REPLACE "/etc/exodaq/" "${_exodaq_etc}/" _exodaq_text "${_exodaq_text}")
  file(WRITE "${_exodaq_gen}/${_exodaq_key}/${_exodaq_name}" "${_exodaq_text}")
  file(INSTALL DESTINATION "${_exodaq_unitdir}" TYPE FILE PERMISSIONS OWNER_READ OWNER_WRITE
    GROUP_READ WORLD_READ FILES "${_exodaq_gen}/${_exodaq_key}/${_exodaq_name}")
endforeach()
file(INSTALL DESTINATION "${_exodaq_unitdir}" TYPE FILE PERMISSIONS OWNER_READ OWNER_WRITE
  GROUP_READ WORLD_READ FILES "${_exodaq_slice}")
file(INSTALL DESTINATION "${_exodaq_sysusersdir}" TYPE FILE RENAME exodaq.conf
  PERMISSIONS OWNER_READ OWNER_WRITE GROUP_READ WORLD_READ FILES "${_exodaq_sysusers}")
# Configuration: readable by the exodaq user, writable by root only.
set(_exodaq_mode PERMISSIONS OWNER_READ OWNER_WRITE GROUP_READ WORLD_READ)
file(INSTALL DESTINATION "${_exodaq_etc}" TYPE FILE ${_exodaq_mode} FILES ${_exodaq_configs})
file(INSTALL DESTINATION "${_exodaq_etc}/models" TYPE FILE ${_exodaq_mode} FILES ${_exodaq_models})
file(INSTALL DESTINATION "${_exodaq_etc}/calibration" TYPE FILE ${_exodaq_mode}
  FILES ${_exodaq_calibrations})
file(INSTALL DESTINATION "${_exodaq_etc}/tasks" TYPE FILE ${_exodaq_mode} FILES ${_exodaq_tasks})
]==])

install(FILES ${EXODAQ_INSTALL_DOCS} DESTINATION ${CMAKE_INSTALL_DOCDIR})
install(FILES ${EXODAQ_SOURCE_SYSTEMD_DIR}/80-can0.network ${EXODAQ_SOURCE_SYSTEMD_DIR}/80-can0.link
  DESTINATION ${CMAKE_INSTALL_DOCDIR}/examples)

# ---------------------------------------------------------------- the .deb
# `cpack -G DEB --config build/CPackConfig.cmake` (or `ninja package` in build/)
# writes build/exodaq_<version>-<release>_<arch>.deb. One package with every
# component. Library dependencies come from dpkg-shlibdeps (liblcm1,
# libyaml-cpp0.7, libspdlog1.10, libfmt9, libsystemd0, libglib2.0-0, libceres3, ...).
set(CPACK_PACKAGE_NAME exodaq)
set(CPACK_PACKAGE_VENDOR "exodaq")
set(CPACK_PACKAGE_CONTACT "exodaq maintainers <exodaq@localhost>")
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY
  "1 kHz encoder acquisition service for a passive macaque exoskeleton (LCM)")
set(CPACK_PACKAGE_DESCRIPTION
  "exodaqd reads six quadrature encoders at 1 kHz over SocketCAN, homes each joint on its\n\
index, applies the calibration and forward kinematics and publishes joint states, palm\n\
poses and a 10 Hz status over LCM. Includes the exodaq tools, the LCM client kit and\n\
the systemd unit.")
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_GENERATOR DEB)
set(CPACK_DEBIAN_PACKAGE_RELEASE 1)
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_PACKAGE_SECTION science)
set(CPACK_DEBIAN_PACKAGE_PRIORITY optional)
set(CPACK_DEB_COMPONENT_INSTALL OFF)
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
# RelWithDebInfo binaries carry about 70 MB of debug information: the package does not.
set(CPACK_STRIP_FILES ON)
# systemd: systemd-sysusers in postinst and the unit; the rest is for clients and the rig.
set(CPACK_DEBIAN_PACKAGE_DEPENDS "systemd")
set(CPACK_DEBIAN_PACKAGE_RECOMMENDS "chrony | time-daemon, can-utils")
# The Python package needs only python3's standard library (Debian 12 has no LCM
# Python module; the package brings its own receiver).
set(CPACK_DEBIAN_PACKAGE_SUGGESTS "liblcm-java, default-jre-headless, python3")

# Maintainer scripts and conffiles, generated into the build tree.
set(_exodaq_deb ${CMAKE_BINARY_DIR}/debian)
file(MAKE_DIRECTORY ${_exodaq_deb})
set(_exodaq_conffiles "")
foreach(f ${EXODAQ_INSTALL_CONFIGS})
  get_filename_component(n ${f} NAME)
  string(APPEND _exodaq_conffiles "/etc/exodaq/${n}\n")
endforeach()
foreach(f ${EXODAQ_INSTALL_MODELS})
  get_filename_component(n ${f} NAME)
  string(APPEND _exodaq_conffiles "/etc/exodaq/models/${n}\n")
endforeach()
foreach(f ${EXODAQ_INSTALL_CALIBRATIONS})
  get_filename_component(n ${f} NAME)
  string(APPEND _exodaq_conffiles "/etc/exodaq/calibration/${n}\n")
endforeach()
foreach(f ${EXODAQ_INSTALL_TASKS})
  get_filename_component(n ${f} NAME)
  string(APPEND _exodaq_conffiles "/etc/exodaq/tasks/${n}\n")
endforeach()
file(WRITE ${_exodaq_deb}/conffiles "${_exodaq_conffiles}")

# DPKG_ROOT: set by `dpkg --root=R --force-script-chrootless` (tests/packaging); the
# scripts then act on R and leave the running system alone.
file(WRITE ${_exodaq_deb}/postinst [==[#!/bin/sh
# exodaq postinst: the service user, then systemd picks up the (new) unit.
set -e
if [ "$1" = "configure" ]; then
    if command -v systemd-sysusers >/dev/null 2>&1; then
        systemd-sysusers ${DPKG_ROOT:+--root="$DPKG_ROOT"} exodaq.conf
    elif ! getent passwd exodaq >/dev/null 2>&1 && [ -z "$DPKG_ROOT" ]; then
        adduser --system --group --no-create-home --home / \
            --gecos "exodaq acquisition service" exodaq
    fi
    # The Python package's byte code, as dh_python3 does (py3clean in prerm).
    if [ -z "$DPKG_ROOT" ] && command -v py3compile >/dev/null 2>&1; then
        py3compile -p exodaq
    fi
    if [ -z "$DPKG_ROOT" ] && [ -d /run/systemd/system ]; then
        systemctl daemon-reload || true
        # An upgrade: the running service moves to the new binary. A first
        # install leaves the service disabled until can0 and the config are
        # ready (docs/operations.md).
        if [ -n "$2" ]; then
            systemctl try-restart exodaqd.service || true
        fi
    fi
fi
exit 0
]==])
file(WRITE ${_exodaq_deb}/prerm [==[#!/bin/sh
set -e
if [ "$1" = "remove" ] && [ -z "$DPKG_ROOT" ] && [ -d /run/systemd/system ]; then
    systemctl stop exodaqd.service || true
fi
if [ -z "$DPKG_ROOT" ] && command -v py3clean >/dev/null 2>&1; then
    py3clean -p exodaq
fi
exit 0
]==])
file(WRITE ${_exodaq_deb}/postrm [==[#!/bin/sh
set -e
if [ -z "$DPKG_ROOT" ] && [ -d /run/systemd/system ]; then
    if [ "$1" = "remove" ] || [ "$1" = "purge" ]; then
        systemctl daemon-reload || true
    fi
    if [ "$1" = "purge" ]; then
        systemctl disable exodaqd.service >/dev/null 2>&1 || true
    fi
fi
# The exodaq user stays (Debian practice: files it owned may remain).
exit 0
]==])
file(CHMOD ${_exodaq_deb}/postinst ${_exodaq_deb}/prerm ${_exodaq_deb}/postrm
  PERMISSIONS OWNER_READ OWNER_WRITE OWNER_EXECUTE GROUP_READ GROUP_EXECUTE WORLD_READ
  WORLD_EXECUTE)
set(CPACK_DEBIAN_PACKAGE_CONTROL_EXTRA
  ${_exodaq_deb}/conffiles ${_exodaq_deb}/postinst ${_exodaq_deb}/prerm ${_exodaq_deb}/postrm)
set(CPACK_DEBIAN_PACKAGE_CONTROL_STRICT_PERMISSION ON)

include(CPack)
