# Script mode (cmake -DIN=file -DSYM=name -DOUT=file.c -P embed.cmake): writes IN as a
# NUL-terminated C char array SYM (and SYM_len, without the NUL) into OUT.
file(READ "${IN}" hex HEX)
string(REGEX REPLACE "(..)" "0x\\1," bytes "${hex}")
string(REGEX REPLACE "((0x..,){16})" "\\1\n  " bytes "${bytes}")
string(LENGTH "${hex}" nhex)
math(EXPR n "${nhex} / 2")
file(WRITE "${OUT}.tmp"
     "/* Generated from ${IN} by server/embed.cmake: do not edit. */\n#include <stddef.h>\n\n"
     "const char ${SYM}[] = {\n  ${bytes}0x00};\nconst size_t ${SYM}_len = ${n};\n")
file(RENAME "${OUT}.tmp" "${OUT}")
