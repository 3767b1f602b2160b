# The man page maglead(1), made at build time from the commands' own --help: manpage_commands.py
# writes help2man's include file (NAME, DESCRIPTION, a COMMANDS section with every command's
# usage and options, SEE ALSO), help2man the page, gzip build/man/maglead.1.gz. Installed as
# share/man/man1/maglead.1.gz in the runtime component (cmake --install and the .deb).
# Needs help2man (tools/setup.sh installs it); without it the build warns and ships no page.
find_program(MAGLEAD_HELP2MAN help2man)
find_program(MAGLEAD_GZIP gzip)
find_package(Python3 COMPONENTS Interpreter QUIET)
if(NOT MAGLEAD_HELP2MAN OR NOT MAGLEAD_GZIP OR NOT Python3_Interpreter_FOUND)
  message(WARNING "help2man, gzip or python3 not found (tools/setup.sh installs them): no man page maglead(1)")
  return()
endif()
set(MAGLEAD_MAN_DIR ${CMAKE_BINARY_DIR}/man)
add_custom_command(
  OUTPUT ${MAGLEAD_MAN_DIR}/maglead.1.gz
  BYPRODUCTS ${MAGLEAD_MAN_DIR}/maglead.1 ${MAGLEAD_MAN_DIR}/commands.h2m
  COMMAND ${CMAKE_COMMAND} -E make_directory ${MAGLEAD_MAN_DIR}
  # Without COLUMNS: --help wraps to it (main.cpp), and the page takes every line whole.
  COMMAND ${CMAKE_COMMAND} -E env --unset=COLUMNS ${Python3_EXECUTABLE}
          ${CMAKE_CURRENT_LIST_DIR}/manpage_commands.py $<TARGET_FILE:maglead>
          ${MAGLEAD_MAN_DIR}/commands.h2m
  COMMAND ${CMAKE_COMMAND} -E env --unset=COLUMNS ${MAGLEAD_HELP2MAN} --no-info --section 1 --version-string ${PROJECT_VERSION}
          --include ${MAGLEAD_MAN_DIR}/commands.h2m --output ${MAGLEAD_MAN_DIR}/maglead.1
          $<TARGET_FILE:maglead>
  COMMAND ${MAGLEAD_GZIP} -9 -n -f -k ${MAGLEAD_MAN_DIR}/maglead.1
  DEPENDS maglead ${CMAKE_CURRENT_LIST_DIR}/manpage_commands.py
  COMMENT "Generating the man page maglead(1) from the commands' --help (help2man)"
  VERBATIM)
add_custom_target(maglead_manpage ALL DEPENDS ${MAGLEAD_MAN_DIR}/maglead.1.gz)
install(FILES ${MAGLEAD_MAN_DIR}/maglead.1.gz DESTINATION ${CMAKE_INSTALL_MANDIR}/man1 COMPONENT runtime)
