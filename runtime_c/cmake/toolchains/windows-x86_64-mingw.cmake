# Windows x86-64 from Linux with MinGW-w64 (apt install gcc-mingw-w64-x86-64-posix); programs
# built here run under wine (apt install wine64). The posix variant of the compiler brings the
# pthreads the test suite uses; the DLL itself imports only KERNEL32 and msvcrt.
set(CMAKE_SYSTEM_NAME Windows)
set(CMAKE_SYSTEM_PROCESSOR AMD64)
set(MCD_TRIPLE x86_64-w64-mingw32)
find_program(MCD_MINGW_GCC NAMES ${MCD_TRIPLE}-gcc-posix ${MCD_TRIPLE}-gcc)
set(CMAKE_C_COMPILER ${MCD_MINGW_GCC})
find_program(MCD_MINGW_GXX NAMES ${MCD_TRIPLE}-g++-posix ${MCD_TRIPLE}-g++)
if(MCD_MINGW_GXX)
  set(CMAKE_CXX_COMPILER ${MCD_MINGW_GXX})
endif()
set(CMAKE_RC_COMPILER ${MCD_TRIPLE}-windres)
list(APPEND CMAKE_FIND_ROOT_PATH /usr/${MCD_TRIPLE})
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE BOTH)
# Debian keeps the 64-bit loader out of PATH, in /usr/lib/wine.
find_program(MCD_WINE NAMES wine64 wine PATHS /usr/lib/wine)
if(MCD_WINE)
  set(CMAKE_CROSSCOMPILING_EMULATOR ${MCD_WINE})
endif()
