#!/bin/sh
# Instructions per pose under callgrind of the RMAL v2 reader (runtime_c, through
# bench/rmal_v3_poses.c: modes none, seq, rand, step2) and of the v3 prototypes on the same keys
# (bench/rmal_v3_proto.c for .v3p files, bench/rmal_v3_eb.c for .v3e: modes 3, 0, 1, 2).
#   bench/rmal_v3_callgrind.sh OUT_DIR FILE...     (FILE: .mcd, .v3p or .v3e)
# Per pose = (Ir of a mode - Ir of the load-only mode) / poses of the mode. Two runs at a time.
set -e
out=$1
shift
root=$(cd "$(dirname "$0")/.." && pwd)
mkdir -p "$out"
flags="-O3 -march=x86-64-v2 -DNDEBUG -std=c99"
warn="-Wall -Wextra -pedantic -Werror"
gcc $flags $warn -I"$root/runtime_c/include" "$root"/runtime_c/src/*.c "$root/bench/rmal_v3_poses.c" -lm -o "$out/once"
# The prototypes use the runtime's rotation and segment arithmetic (runtime_c/src/internal.h,
# curve.c), linked from the runtime's objects.
mkdir -p "$out/rt"
(cd "$out/rt" && gcc $flags $warn -c -I"$root/runtime_c/include" "$root"/runtime_c/src/*.c && ar rcs ../rt.a ./*.o)
for p in proto eb; do
    gcc $flags $warn -I"$root/runtime_c/include" -I"$root/runtime_c/src" \
        "$root/bench/rmal_v3_$p.c" "$out/rt.a" -lm -o "$out/$p"
done
jobs=""
for f in "$@"; do
    case $f in
    *.mcd) bin=once modes="none seq rand step2" ;;
    *.v3p) bin=proto modes="3 0 1 2" ;;
    *) bin=eb modes="3 0 1 2" ;;
    esac
    for m in $modes; do jobs="$jobs $bin:$m:$f"; done
done
echo $jobs | tr ' ' '\n' | xargs -P 2 -I{} sh -c '
    bin=${1%%:*} rest=${1#*:}; m=${rest%%:*} f=${rest#*:}; n=$(basename "$f")
    valgrind --tool=callgrind --callgrind-out-file="$0/$n.$m.cg" "$0/$bin" "$f" "$m" > "$0/$n.$m.log" 2>&1' "$out" {}
for f in "$@"; do
    n=$(basename "$f")
    case $f in *.mcd) set -- none seq rand step2 ;; *) set -- 3 0 1 2 ;; esac
    base=$(grep -o 'refs: *[0-9,]*' "$out/$n.$1.log" | tr -dc 0-9)
    for m in $2 $3 $4; do
        ir=$(grep -o 'refs: *[0-9,]*' "$out/$n.$m.log" | tr -dc 0-9)
        poses=$(grep -o 'poses [0-9]*' "$out/$n.$m.log" | tr -dc 0-9)
        echo "$n $m: $(( (ir - base) / poses )) instructions per pose ($ir Ir, $poses poses, load only $base Ir)"
    done
done
