"""sgjax.files.write_atomic: a result file is replaced whole or not at all, even when the
writing process is killed with SIGKILL mid-write."""

import json
import os
import signal
import stat
import subprocess
import sys
import time

import pytest

from sgjax.files import write_atomic

WRITER = """
import json, sys
from sgjax.files import write_atomic
texts = [json.dumps({"n": n, "rows": [[i] * 50 for i in range(40000)]}) for n in (0, 1)]
for n in range(10**6):  # ~10 MB at a time, the writing (not the encoding) is the loop's time
    write_atomic(sys.argv[1], texts[n % 2])
    print(n, flush=True)
"""


def test_write_atomic_replaces_the_file_with_the_usual_permissions(tmp_path):
    path = tmp_path / "results.json"
    write_atomic(path, "first")
    write_atomic(path, b"second")
    assert path.read_text() == "second"
    umask = os.umask(0)
    os.umask(umask)
    assert stat.S_IMODE(path.stat().st_mode) == 0o666 & ~umask
    assert [p.name for p in tmp_path.iterdir()] == ["results.json"]  # no partial file left


def test_a_failed_write_keeps_the_previous_file(tmp_path, monkeypatch):
    path = tmp_path / "results.json"
    write_atomic(path, "previous")

    def disk_full(fd):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "fsync", disk_full)
    with pytest.raises(OSError, match="No space left"):
        write_atomic(path, "new")
    assert path.read_text() == "previous"
    assert [p.name for p in tmp_path.iterdir()] == ["results.json"]


def test_a_writer_killed_mid_write_leaves_a_whole_file(tmp_path):
    path = tmp_path / "results.json"
    writer = subprocess.Popen([sys.executable, "-c", WRITER, str(path)],
                              stdout=subprocess.PIPE, text=True)
    try:
        assert writer.stdout.readline().strip() == "0"  # one whole file written
        time.sleep(0.3)  # then kill it while it writes a later one
    finally:
        writer.send_signal(signal.SIGKILL)
        writer.wait()
    document = json.loads(path.read_text())  # whole: it parses
    assert len(document["rows"]) == 40000 and document["n"] in (0, 1)
