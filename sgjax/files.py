"""Writing result files so that a crash never leaves half of one.

:func:`write_atomic` writes to a temporary file in the same folder, flushes it to disk and
renames it over the target (``os.replace``, atomic on POSIX and Windows): a reader, or a run
killed with ``kill -9`` mid-write, sees the previous file whole or the new one whole, never a
mixture. Used for every results file, map save and autosave (checkpoints do the same in
``train.run.checkpoint``).
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

_UMASK = os.umask(0)  # read once (setting it is the only way to read it) and put back
os.umask(_UMASK)


def write_atomic(path: str | Path, data: str | bytes) -> Path:
    """Replace ``path`` with ``data`` (text as UTF-8) in one step; returns the path."""
    path = Path(path)
    raw = data.encode() if isinstance(data, str) else data
    handle, temporary = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".partial",
                                         dir=path.parent)
    try:
        os.chmod(temporary, 0o666 & ~_UMASK)  # as open() would create it, not mkstemp's 0600
        with os.fdopen(handle, "wb") as out:
            out.write(raw)
            out.flush()
            os.fsync(out.fileno())
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise
    return path
