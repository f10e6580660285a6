#!/usr/bin/env bash
# The viewer's tests: the committed page parts are what the sources build, and the pages that
# `mocodec view` writes work in headless Chromium (Debian's, installed here when missing; the
# browser tests are skipped, loudly, when it cannot be).
#   FIXTURES=DIR: the web binding's fixtures (bindings/web/test/make_fixtures.py), made if absent.
#   SHOTS=DIR: keep the screenshots there.
set -euo pipefail
cd "$(dirname "$0")"
ROOT=$(cd .. && pwd)
PY=${PYTHON:-$ROOT/.venv/bin/python}
STATIC=$ROOT/encoder/mocodec/view/static
source "$ROOT/tests/apt_need.sh"

[ -d node_modules ] || npm ci --no-audit --no-fund --silent
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT

# The page parts users get are the ones the sources make (`make web` refreshes them).
node build.mjs --out "$WORK/static"
stale=0
cmp -s "$WORK/static/viewer.js" "$STATIC/viewer.js" || { echo "!! $STATIC/viewer.js is not what viewer/ builds: run make web" >&2; stale=1; }
make -s -C "$ROOT/runtime_c" wasm >/dev/null
cmp -s "$ROOT/runtime_c/build/wasm/mocodec.wasm" "$STATIC/mocodec.wasm" || { echo "!! $STATIC/mocodec.wasm is not what runtime_c builds: run make web" >&2; stale=1; }
[ "$stale" = 0 ] && echo "viewer: committed page parts match the sources"

if [ ! -x /usr/bin/chromium ] && ! apt_need chromium; then
  echo "!! SKIPPING the browser tests: Chromium is not installed and cannot be"
  exit "$stale"
fi

FIXTURES=${FIXTURES:-$WORK/fixtures}
[ -f "$FIXTURES/skipped.json" ] || "$PY" "$ROOT/bindings/web/test/make_fixtures.py" "$FIXTURES"
PAGES=$WORK/pages
mkdir -p "$PAGES"
for asset in "$FIXTURES"/*.mcd; do
  codec=$(basename "$asset" .mcd)
  "$ROOT/.venv/bin/mocodec" view "$asset" --original "$FIXTURES"/*.bvh -o "$PAGES/$codec.html" -q
  cp "$FIXTURES/$codec.json" "$PAGES/"
done
"$PY" - "$FIXTURES/rma.mcd" "$PAGES/damaged.mcd" <<'PY'
import sys
data = bytearray(open(sys.argv[1], "rb").read())
data[len(data) // 2] ^= 0x5A  # one flipped byte: the checksum no longer matches
open(sys.argv[2], "wb").write(bytes(data))
PY
"$ROOT/.venv/bin/mocodec" view "$PAGES/damaged.mcd" -o "$PAGES/damaged.html" -q 2>/dev/null
MOCODEC_VIEW_PAGES="$PAGES" MOCODEC_VIEW_SHOTS="${SHOTS:-}" node --test test/ || exit 1
exit "$stale"
