#!/bin/sh
# Instructions per pose of .mcd assets through the C runtime, counted by valgrind callgrind, and
# a hash of the poses, so a change to the runtime can be shown to cost fewer instructions for
# the same bits.
#   bench/pose_instructions.sh ASSET.mcd... -- MODE...
#   MODE: seq, step2, rand, back or tick (bench/pose_instructions.c says what each samples).
#   WORLD=1 samples world poses instead of local ones.
# Per pose = (Ir of the mode - Ir of mode none) / poses of the mode. Mode none only opens the
# asset, so reading the file and starting the process drop out.
# Prints one line per asset and mode. Needs gcc and valgrind.
set -eu
me=${0##*/}
usage() {
    echo "usage: $me ASSET.mcd... -- seq|step2|rand|back|tick..." >&2
    exit 2
}

# Modes are the words after "--"; assets are read from "$@" up to "--" below.
modes="" seen=""
for a in "$@"; do
    if [ -z "$seen" ]; then
        [ "$a" != -- ] || seen=1
        continue
    fi
    case $a in
    seq | step2 | rand | back | tick) modes="$modes $a" ;;
    *) echo "$me: unknown mode: $a" >&2; exit 2 ;;
    esac
done
[ -n "$modes" ] && [ "${1:---}" != -- ] || usage
# Check every asset first, so a typo fails at once and not after minutes of callgrind.
for f in "$@"; do
    [ "$f" != -- ] || break
    [ -f "$f" ] && [ -r "$f" ] || { echo "$me: cannot read asset: $f" >&2; exit 1; }
done
command -v valgrind > /dev/null || { echo "$me: valgrind not found" >&2; exit 1; }
world=""
[ "${WORLD:-}" != 1 ] || world=world

root=$(cd "$(dirname "$0")/.." && pwd)
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
trap 'exit 130' INT
trap 'exit 143' TERM
# The flags of the runtime's recorded counts (docs/RESULTS.md); -Werror keeps the build clean.
gcc -O3 -march=x86-64-v2 -DNDEBUG -std=c99 -Wall -Wextra -pedantic -Werror \
    -I"$root/runtime_c/include" "$root"/runtime_c/src/*.c "$root/bench/pose_instructions.c" \
    -lm -o "$tmp/poses"

# Ir of one run under callgrind; the tool's own line ("MODE poses N hash H") goes to $tmp/out.
# One run at a time: callgrind is slow, and the machine is shared.
ir() {
    if ! valgrind --tool=callgrind --callgrind-out-file="$tmp/cg" --log-file="$tmp/log" \
        "$tmp/poses" "$1" "$2" $world > "$tmp/out"; then
        echo "$me: $1 $2: the run failed (not a valid .mcd?)" >&2
        exit 1
    fi
    grep -o 'refs: *[0-9,]*' "$tmp/log" | tr -dc 0-9
}

for f in "$@"; do
    [ "$f" != -- ] || break
    base=$(ir "$f" none)
    for m in $modes; do
        total=$(ir "$f" "$m")
        poses=$(sed 's/.* poses \([0-9]*\) .*/\1/' "$tmp/out")
        [ "$poses" -gt 0 ] || { echo "$me: $f $m: no poses sampled" >&2; exit 1; }
        # The hash comes from a run outside valgrind: hashing under callgrind would add to Ir.
        hash=$(HASH=1 "$tmp/poses" "$f" "$m" $world | sed 's/.* hash //')
        echo "$f $m: $(( (total - base) / poses )) instructions per pose" \
            "($total Ir, $poses poses, open only $base Ir), pose hash $hash"
    done
done
