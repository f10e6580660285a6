# Shared part of the Linux cross toolchains (Debian's gcc-<triple> and libc6-dev-<arch>-cross
# packages): the compiler is <MCD_TRIPLE>-gcc, the target's libraries live in /usr/<MCD_TRIPLE>,
# and programs built here run under qemu-user (qemu-<CMAKE_SYSTEM_PROCESSOR>) with that folder as
# the root for the loader and shared libraries. Included by the per-target files beside it.
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_C_COMPILER ${MCD_TRIPLE}-gcc)
# The C++ compiler only checks that mocodec.h compiles as C++; without g++-<triple> that is skipped.
find_program(MCD_CROSS_GXX ${MCD_TRIPLE}-g++)
if(MCD_CROSS_GXX)
  set(CMAKE_CXX_COMPILER ${MCD_CROSS_GXX})
endif()
list(APPEND CMAKE_FIND_ROOT_PATH /usr/${MCD_TRIPLE})
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
# BOTH: a consumer test finds the mocodec package it just installed outside the target root.
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE BOTH)
find_program(MCD_QEMU qemu-${CMAKE_SYSTEM_PROCESSOR})
if(MCD_QEMU)
  set(CMAKE_CROSSCOMPILING_EMULATOR ${MCD_QEMU} -L /usr/${MCD_TRIPLE})
endif()
