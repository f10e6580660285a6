"""Every bad or odd input of tests/malformed_inputs.py (BVH and glTF, built from the samples)
through `mocodec encode`: an odd file is encoded within the tolerance, a bad one ends with
one line naming the file and the problem; never a traceback, each within 10 s of CPU time (CPU,
not wall time: the machine may be shared), the whole run under 1 GB of memory. The variants run
in one child process (a hang there times out, not the test run)."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from malformed_inputs import variants

RUNNER = r"""
import contextlib, io, json, signal, sys, time
from mocodec.cli import main, _peak_rss_kib  # VmHWM: ru_maxrss would count the pytest worker forked from

def alarm(signum, frame):
    raise TimeoutError("over 10 s of CPU time")

signal.signal(signal.SIGPROF, alarm)
for path in sys.argv[1:]:
    out, err = io.StringIO(), io.StringIO()
    start = time.process_time()
    signal.setitimer(signal.ITIMER_PROF, 10.0)
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            code = main(["encode", path, "-o", path + ".mcd", "--json"])
    except BaseException as exc:  # a hang (the alarm) or anything main() let through
        code = "raised " + type(exc).__name__ + ": " + str(exc)[:200]
    signal.setitimer(signal.ITIMER_PROF, 0.0)
    peak = _peak_rss_kib() * 1024
    print(json.dumps({"path": path, "code": code, "stdout": out.getvalue(), "stderr": err.getvalue(),
                      "seconds": time.process_time() - start, "peak_bytes": peak}), flush=True)
"""


def test_every_malformed_input_is_refused_in_one_line_or_encoded(tmp_path: Path) -> None:
    cases = variants()
    assert len(cases) >= 60
    paths = []
    for i, (name, file, data, expected) in enumerate(cases):
        path = tmp_path / f"{i:03d}_{file}"
        path.write_bytes(data)
        paths.append(str(path))
    r = subprocess.run([sys.executable, "-c", RUNNER, *paths], capture_output=True, text=True,
                       timeout=30 + 10 * len(cases))
    rows = [json.loads(line) for line in r.stdout.splitlines()]
    assert len(rows) == len(cases), r.stderr[-2000:]
    problems = []
    for (name, file, data, expected), row in zip(cases, rows):
        err_lines = row["stderr"].splitlines()
        errors = [ln for ln in err_lines if ln.startswith("mocodec: error:")]
        if "Traceback" in row["stderr"] or isinstance(row["code"], str):
            problems.append(f"{name}: {row['code']} {row['stderr'][-300:]}")
        elif row["seconds"] > 10:
            problems.append(f"{name}: {row['seconds']:.1f} s of CPU time")
        elif expected == "refuse":
            if row["code"] == 0 or len(errors) != 1 or row["path"] not in errors[0] or len(errors[0]) > 400:
                problems.append(f"{name}: expected one error line naming the file, got code {row['code']}: "
                                f"{row['stderr'][-300:]!r}")
        else:
            if row["code"] != 0:
                problems.append(f"{name}: expected it encoded, got {row['stderr'][-300:]!r}")
            elif json.loads(row["stdout"])["error"]["max_cm"] > 1.0 + 1e-6:
                problems.append(f"{name}: error {json.loads(row['stdout'])['error']['max_cm']} cm over 1 cm")
    assert not problems, "\n".join(problems)
    assert max(row["peak_bytes"] for row in rows) < 1 << 30
