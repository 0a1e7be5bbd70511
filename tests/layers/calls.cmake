# Proves that no layer of the renderer calls up the layers (cmake -P): every symbol a layer's
# objects use (nm's undefined symbols: functions called, data read) must be defined by the layer
# itself, a layer below it, or outside the renderer (libc, Embree, Vulkan, ...); one defined by a
# layer above it, or by a sibling of the same rank (the two backends), is a violation named with
# the object that uses it and the layer that defines it. The include rule (check.cmake) cannot
# see this: a declaration in a public header lets core call the registry.
#   -DNM=<nm> -DLAYERS=<name:rank|...> (bottom up) -DOBJS_<name>=<objects, |-list> per layer
foreach(v NM LAYERS)
  if(NOT DEFINED ${v})
    message(FATAL_ERROR "calls.cmake needs -D${v}=...")
  endif()
endforeach()
string(REPLACE "|" ";" LAYERS "${LAYERS}")

# nm -A -g over one layer's objects: "<object>: <address> <type> <symbol>" per line.
function(layer_symbols layer)
  string(REPLACE "|" ";" objs "${OBJS_${layer}}")
  if(NOT objs)
    message(FATAL_ERROR "calls.cmake: layer ${layer} has no objects")
  endif()
  execute_process(COMMAND ${NM} -A -g ${objs} RESULT_VARIABLE rc OUTPUT_VARIABLE out
                  ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "calls.cmake: ${NM} failed on layer ${layer}: ${err}")
  endif()
  set(out_${layer} "${out}" PARENT_SCOPE)
endfunction()

# First every layer's definitions (def_<symbol> = layer), then every use checked against them.
set(failures 0)
foreach(entry ${LAYERS})
  string(REPLACE ":" ";" pair ${entry})
  list(GET pair 0 layer)
  list(GET pair 1 rank)
  set(rank_${layer} ${rank})
  layer_symbols(${layer})
  string(REGEX MATCHALL "[^\n]+" lines "${out_${layer}}")
  foreach(l ${lines})
    if(l MATCHES "^([^ ]+): *[0-9a-fA-F]+ [A-TV-Za-tv-z] ([A-Za-z_][A-Za-z0-9_.]*)$")
      set(def_${CMAKE_MATCH_2} ${layer})
      # The bottom layer knows no technique and no backend table: it defines none of their
      # functions (it reads descriptors and operations tables handed to it as data).
      if(rank EQUAL 0 AND CMAKE_MATCH_2 MATCHES "^obs_(technique|backend)_")
        get_filename_component(name ${CMAKE_MATCH_1} NAME)
        message(SEND_ERROR "${layer}: ${name} defines ${CMAKE_MATCH_2}, a function of the "
                           "registry's")
        math(EXPR failures "${failures} + 1")
      endif()
    endif()
  endforeach()
endforeach()

set(down 0)
foreach(entry ${LAYERS})
  string(REPLACE ":" ";" pair ${entry})
  list(GET pair 0 layer)
  string(REGEX MATCHALL "[^\n]+" lines "${out_${layer}}")
  foreach(l ${lines})
    if(NOT l MATCHES "^([^ ]+): +U ([A-Za-z_][A-Za-z0-9_.]*)$")
      continue()
    endif()
    set(obj ${CMAKE_MATCH_1})
    set(sym ${CMAKE_MATCH_2})
    set(owner "${def_${sym}}")
    if(NOT owner OR owner STREQUAL layer)
      continue()
    endif()
    if(rank_${owner} LESS rank_${layer})
      math(EXPR down "${down} + 1")
      continue()
    endif()
    get_filename_component(name ${obj} NAME)
    message(SEND_ERROR "${layer}: ${name} uses ${sym}, defined by the ${owner} layer, which is "
                       "not below it")
    math(EXPR failures "${failures} + 1")
  endforeach()
endforeach()
# Uses of lower layers must have been seen, or broken symbol parsing would pass unnoticed.
if(down EQUAL 0)
  message(SEND_ERROR "calls.cmake: no use of a lower layer was found: the probe proved nothing")
  math(EXPR failures "${failures} + 1")
endif()
if(failures)
  message(FATAL_ERROR "${failures} call(s) up the layers")
endif()
message(STATUS "${down} use(s) of lower layers, none up the layers")
