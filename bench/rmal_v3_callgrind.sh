#!/bin/sh
# Instructions per pose of the RMAL v2 reader (runtime_c, via /tmp/ps/once.c or any copy of it)
# and of the v3 prototype (bench/rmal_v3_proto.c) on the same keys, under callgrind.
#   bench/rmal_v3_callgrind.sh OUT_DIR ONCE_C V2_ASSET_1CM V2_ASSET_002 V3P_1CM V3P_002
# Per pose = (Ir of mode m - Ir of mode 3, which only loads) / poses of mode m.
set -e
out=$1 once=$2; a1=$3 a2=$4 p1=$5 p2=$6
root=$(cd "$(dirname "$0")/.." && pwd)
mkdir -p "$out"
flags="-O3 -march=x86-64-v2 -DNDEBUG -std=c99"
nice -n 19 gcc $flags -I"$root/runtime_c/include" "$root"/runtime_c/src/*.c "$once" -lm -o "$out/once"
nice -n 19 gcc $flags -Wall -Wextra -pedantic -Werror "$root/bench/rmal_v3_proto.c" -lm -o "$out/proto"
run() { # name binary file mode
    nice -n 19 valgrind --tool=callgrind --callgrind-out-file="$out/$1.$4.cg" "$2" "$3" "$4" > "$out/$1.$4.log" 2>&1
}
for m in 3 0 1 2; do
    run v2_1cm "$out/once" "$a1" $m; run v2_002 "$out/once" "$a2" $m
    run v3_1cm "$out/proto" "$p1" $m; run v3_002 "$out/proto" "$p2" $m
done
for s in v2_1cm v2_002 v3_1cm v3_002; do
    base=$(grep -o 'refs: *[0-9,]*' "$out/$s.3.log" | tr -dc 0-9)
    for m in 0 1 2; do
        ir=$(grep -o 'refs: *[0-9,]*' "$out/$s.$m.log" | tr -dc 0-9)
        poses=$(grep -o 'poses [0-9]*' "$out/$s.$m.log" | tr -dc 0-9)
        echo "$s mode $m: $(( (ir - base) / poses )) instructions per pose ($ir Ir, $poses poses)"
    done
done
