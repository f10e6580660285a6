# Linux s390x (IBM Z), big-endian, and C99's FLT_EVAL_METHOD 1 (float arithmetic and constants in
# double precision): apt install gcc-s390x-linux-gnu libc6-dev-s390x-cross qemu-user
set(CMAKE_SYSTEM_PROCESSOR s390x)
set(MCD_TRIPLE s390x-linux-gnu)
include(${CMAKE_CURRENT_LIST_DIR}/linux-cross.cmake)
