#!/usr/bin/env bash
# Compiles the C# core (unity_package/Runtime/Core: one copy, used by Unity and by any .NET
# engine) and the NUnit tests that the Unity package ships (unity_package/Tests/Editor) with mono's mcs, runs them with nunit-console 2.6 against
# the real native runtime and assets encoded now, and prints "N passed, N failed".
set -euo pipefail
HERE="$(cd "$(dirname "$0")" && pwd)"
source "$HERE/../common.sh"
OUT="$HERE/build"
mkdir -p "$OUT"

NUNIT_FRAMEWORK="$(ls /usr/lib/cli/nunit.framework-2.6*/nunit.framework.dll 2>/dev/null | head -n1 || true)"
for tool in mcs mono nunit-console; do
    command -v "$tool" >/dev/null || { echo "csharp: $tool not found (apt-get install mono-devel nunit-console)" >&2; exit 2; }
done
[ -n "$NUNIT_FRAMEWORK" ] || { echo "csharp: nunit.framework.dll not found (apt-get install libnunit-cil-dev)" >&2; exit 2; }

lib="$(mcd_shared_lib)"
cp "$lib" "$OUT/libmocodec.so"
mcd_test_data "$OUT/data" >&2

# The C compiler's view of the structs the binding mirrors.
${CC:-cc} -std=c99 -I"$MCD_RUNTIME/include" "$HERE/abi_layout.c" -o "$OUT/abi_layout"
"$OUT/abi_layout" > "$OUT/abi_layout.txt"

# C# 7.2 is the newest that mcs accepts and what the issue promises Unity users.
MCS=(mcs -langversion:7.2 -unsafe -warnaserror+ -nologo)
"${MCS[@]}" -target:library -out:"$OUT/Mocodec.dll" "$MCD_REPO"/unity_package/Runtime/Core/*.cs
"${MCS[@]}" -target:library -out:"$OUT/Mocodec.Tests.dll" -r:"$OUT/Mocodec.dll" -r:"$NUNIT_FRAMEWORK" \
    "$MCD_REPO"/unity_package/Tests/Editor/*.cs
cp "$NUNIT_FRAMEWORK" "$OUT/"

rm -f "$OUT/TestResult.xml"
set +e
( cd "$OUT" && LD_LIBRARY_PATH="$OUT${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}" \
  MOCODEC_TEST_DATA="$OUT/data" MOCODEC_ABI_LAYOUT="$OUT/abi_layout.txt" \
  nunit-console -nologo -xml="$OUT/TestResult.xml" "$OUT/Mocodec.Tests.dll" > "$OUT/nunit.log" 2>&1 )
nunit_rc=$?
set -e

# NUnit 2.6 ends with its own summary, which CI does not read; count the test cases instead.
# A test NUnit could not run (NotRunnable: a bad TestCaseSource, say) counts as failed.
python3 - "$OUT/TestResult.xml" "$OUT/nunit.log" "$nunit_rc" <<'PY'
import sys
import xml.etree.ElementTree as ET
xml_path, log_path, rc = sys.argv[1], sys.argv[2], int(sys.argv[3])
try:
    cases = ET.parse(xml_path).getroot().iter("test-case")
except (OSError, ET.ParseError) as exc:
    print(open(log_path).read()[-4000:])
    print(f"csharp: no readable TestResult.xml ({exc})")
    print("0 passed, 1 failed")
    sys.exit(1)
passed = failed = skipped = 0
for case in cases:
    result = case.get("result")
    if result == "Success":
        passed += 1
    elif result in ("Ignored", "Skipped", "Inconclusive"):
        skipped += 1
        print(f"  skipped: {case.get('name')}")
    else:
        failed += 1
        msg = case.findtext("./failure/message") or case.findtext("./reason/message") or result
        print(f"  FAILED: {case.get('name')}: {msg.strip()[:2000]}")
if failed or rc != 0:
    print(open(log_path).read()[-3000:])
print("csharp tests ran under mono NUnit 2.6 (nunit-console)")
print(f"csharp: {passed} passed, {failed} failed, {skipped} skipped")
sys.exit(1 if failed or rc != 0 or passed == 0 else 0)
PY
