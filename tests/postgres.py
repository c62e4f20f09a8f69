"""A throwaway PostgreSQL server for the tests that share an Optuna study between processes.

:func:`postgres_server` makes a database cluster in a temporary folder (``initdb``), starts a
server on a free loopback port (``pg_ctl``), yields its SQLAlchemy URL and stops and deletes it
afterwards. It needs Debian's ``postgresql`` package (``initdb`` and ``pg_ctl`` on the ``PATH``
or under ``/usr/lib/postgresql/<version>/bin``) and the ``psycopg2`` driver (the
``psycopg2-binary`` wheel of the dev extra). Without them the tests skip with a reason naming
the package, unless ``SGJAX_REQUIRE_POSTGRES=1`` (set by ``.ci/run``, which installs the
package), where a missing server is a failure. PostgreSQL refuses to run as root: as root, the
server runs as the package's ``postgres`` user.
"""

from __future__ import annotations

import contextlib
import glob
import os
import shutil
import socket
import subprocess
import tempfile
from collections.abc import Iterator
from pathlib import Path

import pytest

REQUIRE = "SGJAX_REQUIRE_POSTGRES"


def _missing(reason: str) -> None:
    if os.environ.get(REQUIRE) == "1":
        pytest.fail(f"{reason} ({REQUIRE}=1: this run must test against PostgreSQL)")
    pytest.skip(reason)


def _program(name: str) -> str | None:
    found = shutil.which(name)
    if found:
        return found
    candidates = sorted(glob.glob(f"/usr/lib/postgresql/*/bin/{name}"))
    return candidates[-1] if candidates else None


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@contextlib.contextmanager
def postgres_server() -> Iterator[str]:
    """A running server; yields ``postgresql+psycopg2://sgjax@127.0.0.1:<port>/postgres``."""
    initdb, pg_ctl = _program("initdb"), _program("pg_ctl")
    if initdb is None or pg_ctl is None:
        _missing("PostgreSQL server programs (initdb, pg_ctl) not found: install Debian's "
                 "postgresql package (apt-get install postgresql)")
    try:
        import psycopg2  # noqa: F401
    except ImportError:
        _missing("the psycopg2 driver is not installed: pip install psycopg2-binary (in the "
                 "dev extra)")
    root = Path(tempfile.mkdtemp(prefix="sgjax-postgres-"))
    as_root = os.geteuid() == 0
    prefix: list[str] = []
    if as_root:
        if shutil.which("runuser") is None:
            _missing("running as root and runuser is missing: PostgreSQL runs only as a "
                     "normal user")
        try:
            shutil.chown(root, "postgres")
        except LookupError:
            _missing("running as root without the postgres user that Debian's postgresql "
                     "package creates")
        os.chmod(root, 0o755)
        prefix = ["runuser", "-u", "postgres", "--"]
    data, log = root / "data", root / "server.log"
    port = _free_port()

    def run(*args: str) -> None:
        done = subprocess.run([*prefix, *args], cwd=root, capture_output=True, text=True,
                              timeout=120)
        if done.returncode:
            server_log = log.read_text() if log.exists() else ""
            raise RuntimeError(f"{' '.join(args)} failed ({done.returncode}):\n{done.stdout}"
                               f"\n{done.stderr}\n{server_log}")

    try:
        run(initdb, "-D", str(data), "--auth=trust", "--username=sgjax", "--no-sync",
            "--encoding=UTF8")
        run(pg_ctl, "-D", str(data), "-l", str(log), "-w", "-t", "60", "-o",
            f"-p {port} -k {root} -c listen_addresses=127.0.0.1 -c fsync=off", "start")
        try:
            yield f"postgresql+psycopg2://sgjax@127.0.0.1:{port}/postgres"
        finally:
            run(pg_ctl, "-D", str(data), "-m", "immediate", "-w", "stop")
    finally:
        shutil.rmtree(root, ignore_errors=True)
