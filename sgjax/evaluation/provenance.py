"""Provenance of a result file: which code, on which machine, run how, with which seeds.

Every result sgjax writes (``metrics.json`` of ``sgjax evaluate --out`` and of a training
run's final evaluation, a training run's ``provenance.json``, ``train.reproduce``'s
``results.json``, ``train.ablation``'s ``ablation.json``) carries one block::

    {"schema": "sgjax.provenance/1", "created": "2026-11-25T16:20:00+00:00",
     "git": {"commit": "b73e1b4...", "dirty": false},
     "versions": {"sgjax": "0.4.0", "python": "3.11.2", "jax": "0.10.2", "jaxlib": ...},
     "machine": {"platform": "Linux-...", "cpu": "Intel(R) Xeon(R) ...", "cpu_count": 2,
                 "jax_backend": "cpu", "devices": ["TFRT_CPU_0"]},
     "command": "python -m train --config train/configs/doorway.yaml",
     "config_sha256": "...", "seeds": {"training": [0], "evaluation": [1]},
     "episodes_per_cell": 192, "seconds": {"training": 123.4, ...}}

``git.commit`` is None (with ``git.error`` saying why) outside a git checkout; ``dirty`` says
whether tracked files differed from that commit. Both describe the code the process runs: the
checkout as it was when this module was imported (a command imports it as it starts), not when
a long run writes its result hours later; where the checkout moved in between (a commit, an
edit), the block keeps the starting commit, sets ``dirty`` and names the commit it moved to
under ``git.now`` (the process may have loaded code of both: :func:`run_git_state`). sgjax installed
from a package (a machine without git or without the checkout, such as an offline GPU) takes
the commit from the environment variable ``SGJAX_GIT_COMMIT`` (40 hex digits) when it is set;
the block then says so (``"source": "SGJAX_GIT_COMMIT"``) and ``dirty`` is None (unknown).
The JSON schema of the block is ``PROVENANCE_SCHEMA`` (``docs/results/schema.json`` holds it
with the result files' own schema).
"""

from __future__ import annotations

import datetime
import hashlib
import importlib.metadata
import json
import os
import platform
import re
import shlex
import subprocess
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

SCHEMA = "sgjax.provenance/1"
PACKAGES = ("sgjax", "jax", "jaxlib", "numpy", "flax", "optax")
REPOSITORY = Path(__file__).resolve().parents[2]  # the checkout sgjax runs from, if any

PROVENANCE_SCHEMA: dict[str, Any] = {
    "type": "object",
    "required": ["schema", "created", "git", "versions", "machine", "command"],
    "properties": {
        "schema": {"const": SCHEMA},
        "created": {"type": "string"},
        "git": {"type": "object", "required": ["commit", "dirty"],
                "properties": {"commit": {"type": ["string", "null"],
                                          "pattern": "^[0-9a-f]{40}$"},
                               "dirty": {"type": ["boolean", "null"]},
                               "now": {"type": ["string", "null"]},
                               "error": {"type": "string"}}},
        "versions": {"type": "object", "required": ["sgjax", "python", "jax", "jaxlib", "numpy"],
                     "additionalProperties": {"type": ["string", "null"]}},
        "machine": {"type": "object", "required": ["platform", "cpu", "cpu_count"]},
        "command": {"type": "string"},
        "config_sha256": {"type": "string", "pattern": "^[0-9a-f]{64}$"},
        "seeds": {"type": "object"},
        "episodes_per_cell": {"type": "integer", "minimum": 1},
        "seconds": {"type": "object", "additionalProperties": {"type": "number"}},
    },
}


# Where an installed sgjax (no checkout beside it) learns the commit it was installed from.
COMMIT_VARIABLE = "SGJAX_GIT_COMMIT"


def _git(*args: str) -> str:
    """``git args`` in :data:`REPOSITORY`; its stdout, stripped (raises on failure)."""
    done = subprocess.run(["git", "-C", str(REPOSITORY), *args], capture_output=True,
                          text=True, timeout=30, check=True)
    return done.stdout.strip()


def git_state() -> dict[str, Any]:
    """``{"commit": 40-hex or None, "dirty": bool or None}`` of the checkout sgjax runs from,
    with ``"error"`` saying why where there is none (an installed wheel, git missing)."""
    if not (REPOSITORY / ".git").exists():
        given = os.environ.get(COMMIT_VARIABLE)
        if given is None:
            return {"commit": None, "dirty": None,
                    "error": f"{REPOSITORY} is not a git checkout (sgjax installed from a "
                             f"package) and {COMMIT_VARIABLE} is not set"}
        if not re.fullmatch(r"[0-9a-f]{40}", given):
            raise ValueError(f"{COMMIT_VARIABLE}={given!r}: not a commit (40 lowercase hex "
                             "digits, as `git rev-parse HEAD` prints)")
        return {"commit": given, "dirty": None, "source": COMMIT_VARIABLE}
    try:
        commit = _git("rev-parse", "HEAD")
        dirty = bool(_git("status", "--porcelain", "--untracked-files=no"))
    except (OSError, subprocess.SubprocessError) as err:
        return {"commit": None, "dirty": None, "error": f"git failed: {err}"}
    return {"commit": commit, "dirty": dirty}


_AT_IMPORT = git_state()  # the code this process runs: the checkout as the process started


def run_git_state() -> dict[str, Any]:
    """The git state of the code this process runs: :func:`git_state` as it was when this
    module was imported, or, where the checkout has moved since, that state with ``dirty`` true
    and ``now`` the commit it moved to (the process may have loaded code of both)."""
    now = git_state()
    if now == _AT_IMPORT:
        return now
    return {**_AT_IMPORT, "dirty": True, "now": now.get("commit")}


def versions() -> dict[str, str | None]:
    """Installed versions of python and :data:`PACKAGES` (None: not installed)."""
    found: dict[str, str | None] = {"python": platform.python_version()}
    for name in PACKAGES:
        try:
            found[name] = importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            found[name] = None
    return found


def cpu_model() -> str:
    """The CPU's model name (``/proc/cpuinfo`` on Linux, ``platform.processor()`` elsewhere,
    "unknown" when neither says)."""
    cpuinfo = Path("/proc/cpuinfo")
    if cpuinfo.is_file():
        for line in cpuinfo.read_text(errors="replace").splitlines():
            if line.lower().startswith("model name") and ":" in line:
                return line.split(":", 1)[1].strip()
    return platform.processor() or "unknown"


def machine() -> dict[str, Any]:
    """Platform, CPU model and count, and JAX's backend and devices (this starts JAX's backend,
    so call it when writing results, not at import)."""
    import jax

    return {"platform": platform.platform(), "cpu": cpu_model(), "cpu_count": os.cpu_count(),
            "jax_backend": jax.default_backend(),
            "devices": [f"{d.platform}:{d.device_kind}" for d in jax.devices()]}


def command_line() -> str:
    """The command as typed (``python -m train --config ...``), from ``sys.orig_argv``."""
    argv = list(getattr(sys, "orig_argv", None) or [sys.executable, *sys.argv])
    if argv and Path(argv[0]).name.startswith("python"):
        argv[0] = "python"
    return shlex.join(argv)


def config_hash(config: Any) -> str:
    """SHA-256 of a resolved configuration, as canonical JSON (keys sorted; values JSON cannot
    hold written with ``str``)."""
    text = json.dumps(config, sort_keys=True, default=str, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()


def provenance(config: Any = None, seeds: Mapping[str, Sequence[int]] | None = None,
               episodes_per_cell: int | None = None,
               seconds: Mapping[str, float] | None = None) -> dict[str, Any]:
    """The provenance block of a result written now (see the module docstring): ``config``
    (any JSON-able resolved configuration) is hashed, ``seeds`` maps a role (``training``,
    ``evaluation``, ``validation``) to its seeds, ``seconds`` each phase's wall time."""
    block: dict[str, Any] = {
        "schema": SCHEMA,
        "created": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "git": run_git_state(), "versions": versions(), "machine": machine(),
        "command": command_line(),
    }
    if config is not None:
        block["config_sha256"] = config_hash(config)
    if seeds is not None:
        block["seeds"] = {role: [int(s) for s in values] for role, values in seeds.items()}
    if episodes_per_cell is not None:
        block["episodes_per_cell"] = int(episodes_per_cell)
    if seconds is not None:
        block["seconds"] = {phase: round(float(s), 3) for phase, s in seconds.items()}
    return block
