# Proves the layering rule for one layer (cmake -P): every header of a layer that is not on the
# layer's include path fails to compile when included from the layer's context, every header of
# its own directory (and of the folders below it: the technique folders) compiles there, and no
# source of the layer reaches another directory by a relative include (which a private include
# path could not stop).
#   -DCC=<C compiler> -DLAYER=<name> -DDIR=<the layer's sources> -DINC=<include path, |-list>
#   -DSRC=<source root> -DWORK=<scratch directory>
foreach(v CC LAYER DIR INC SRC WORK)
  if(NOT DEFINED ${v})
    message(FATAL_ERROR "check.cmake needs -D${v}=...")
  endif()
endforeach()
string(REPLACE "|" ";" INC "${INC}")
# A source always sees its own directory (the quote form looks there first).
list(APPEND INC ${DIR})
list(REMOVE_DUPLICATES INC)
file(MAKE_DIRECTORY ${WORK})
set(flags -std=c11 -fsyntax-only -Wall -Werror -D_POSIX_C_SOURCE=200809L -D_DEFAULT_SOURCE)
foreach(d ${INC})
  list(APPEND flags -I${d})
endforeach()

# Compiles a probe that includes `header` (from WORK, so the quote form finds nothing beside it);
# sets ok (1 when it compiled) and out (the compiler's messages).
function(probe header)
  string(MAKE_C_IDENTIFIER ${header} id)
  set(probe_c ${WORK}/probe_${id}.c)
  file(WRITE ${probe_c} "#include \"${header}\"\nint obs_layer_probe;\n")
  execute_process(COMMAND ${CC} ${flags} ${probe_c} RESULT_VARIABLE rc OUTPUT_VARIABLE o
                  ERROR_VARIABLE o)
  if(rc EQUAL 0)
    set(ok 1 PARENT_SCOPE)
  else()
    set(ok 0 PARENT_SCOPE)
  endif()
  set(out "${o}" PARENT_SCOPE)
endfunction()

set(failures 0)
set(forbidden 0)
set(own 0)
file(GLOB dirs LIST_DIRECTORIES true ${SRC}/renderer/* ${SRC}/renderer/techniques/* ${SRC}/server)
foreach(d ${dirs})
  if(NOT IS_DIRECTORY ${d} OR d MATCHES "/renderer/include$")
    continue()
  endif()
  file(GLOB headers ${d}/*.h)
  list(FIND INC ${d} visible)
  foreach(h ${headers})
    get_filename_component(name ${h} NAME)
    probe(${name})
    if(visible EQUAL -1)
      math(EXPR forbidden "${forbidden} + 1")
      string(REGEX REPLACE "([.+])" "\\\\\\1" re ${name})
      if(ok OR NOT out MATCHES "${re}'?: No such file|'${re}' file not found")
        message(SEND_ERROR "${LAYER}: ${d}/${name} is not on the layer's include path, yet "
                           "including it did not fail as a missing file:\n${out}")
        math(EXPR failures "${failures} + 1")
      endif()
    elseif(d STREQUAL DIR OR d MATCHES "^${DIR}/")
      if(ok)
        math(EXPR own "${own} + 1")
      else()
        message(SEND_ERROR "${LAYER}: its own header ${name} does not compile in its context:\n"
                           "${out}")
        math(EXPR failures "${failures} + 1")
      endif()
    endif()
  endforeach()
endforeach()
# Both directions must have been exercised, or a broken include path would pass unnoticed.
if(forbidden EQUAL 0 OR own EQUAL 0)
  message(SEND_ERROR "${LAYER}: ${forbidden} header(s) out of reach, ${own} of its own compiled: "
                     "the probe proved nothing")
  math(EXPR failures "${failures} + 1")
endif()

# Relative includes: only "obscura/..." (the public headers) may name a directory.
file(GLOB sources ${DIR}/*.c ${DIR}/*.h ${DIR}/*/*.c ${DIR}/*/*.h)
foreach(f ${sources})
  file(STRINGS ${f} lines REGEX "^[ \t]*#[ \t]*include[ \t]*\"[^\"]*/")
  foreach(l ${lines})
    if(NOT l MATCHES "\"obscura/[^/\"]+\"")
      message(SEND_ERROR "${LAYER}: ${f} reaches past its include path: ${l}")
      math(EXPR failures "${failures} + 1")
    endif()
  endforeach()
endforeach()
if(failures)
  message(FATAL_ERROR "${LAYER}: ${failures} layering violation(s)")
endif()
message(STATUS "${LAYER}: ${forbidden} header(s) of other layers out of reach, ${own} of its own "
               "compile")
