"""JAX's persistent compilation cache for the command-line tools, on by default.

A command compiles its environment step, training update and evaluation run; with the cache a
second run of any command (same shapes, same jax and jaxlib) loads those programs from disk
instead of compiling them again. JAX's own cache does the work (``jax_compilation_cache_dir``);
this module only chooses the folder and the thresholds:

- the folder: ``$SGJAX_COMPILATION_CACHE`` if set, else ``$XDG_CACHE_HOME/sgjax/jax`` (by
  default ``~/.cache/sgjax/jax``); delete it to clear the cache;
- every program is kept (no minimum compile time or size: a mini-game's many small compiles
  add up);
- a cache folder configured for JAX already (``JAX_COMPILATION_CACHE_DIR`` or
  ``jax.config.update``) is kept as it is.

Turn it off with ``--no-compilation-cache`` on any command, or ``SGJAX_NO_COMPILATION_CACHE=1``.

The commands also compile XLA:CPU programs with its elemental emitters
(``--xla_cpu_use_fusion_emitters=false`` appended to ``XLA_FLAGS`` before JAX starts its
backends): the same arithmetic and about the same speed once compiled, in less compile time
(``bench/compile_time.py`` and docs/benchmark.md measure both). It changes nothing on a GPU.
Keep XLA's default with ``SGJAX_XLA_DEFAULT_EMITTERS=1`` or by putting
``--xla_cpu_use_fusion_emitters`` in ``XLA_FLAGS`` yourself. Only jaxlib 0.10 gets the flag:
0.11 dropped it (XLA aborts on a flag it does not know).

The trainer's update is the exception (:func:`learner_compiler_options`): where the commands
chose the elemental emitters, it compiles with XLA's default ones (``jax.jit(...,
compiler_options=...)``), which run its matmul-heavy learning phase faster for a little more
compile (``bench/learner_roofline.py``); every other program keeps the fast compile.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

import jax

ENV_DIR = "SGJAX_COMPILATION_CACHE"
ENV_OFF = "SGJAX_NO_COMPILATION_CACHE"
ENV_DEFAULT_EMITTERS = "SGJAX_XLA_DEFAULT_EMITTERS"
FAST_CPU_COMPILE = "--xla_cpu_use_fusion_emitters=false"
# What the trainer's update compiles with where fast_cpu_compile chose the elemental emitters.
LEARNER_COMPILER_OPTIONS = {"xla_cpu_use_fusion_emitters": True}
_chose_elemental = False  # fast_cpu_compile appended FAST_CPU_COMPILE in this process


def fast_cpu_compile() -> bool:
    """Append :data:`FAST_CPU_COMPILE` to ``XLA_FLAGS`` unless the user chose otherwise or JAX's
    backends already started (then it is too late and nothing changes). Returns whether the flag
    is in effect for this process."""
    from jax._src import xla_bridge

    flags = os.environ.get("XLA_FLAGS", "")
    name = FAST_CPU_COMPILE.split("=")[0]
    if name in flags:
        return FAST_CPU_COMPILE in flags
    if os.environ.get(ENV_DEFAULT_EMITTERS) == "1" or xla_bridge.backends_are_initialized():
        return False
    if not knows_fast_cpu_compile():
        return False
    os.environ["XLA_FLAGS"] = f"{flags} {FAST_CPU_COMPILE}".strip()
    global _chose_elemental
    _chose_elemental = True
    return True


def learner_compiler_options() -> dict[str, bool] | None:
    """``compiler_options`` for ``jax.jit`` of a training update: XLA:CPU's default fusion
    emitters (:data:`LEARNER_COMPILER_OPTIONS`) where :func:`fast_cpu_compile` chose the
    elemental ones for this process, else None (the process's own flags: a user's
    ``XLA_FLAGS``, ``SGJAX_XLA_DEFAULT_EMITTERS=1``, a jaxlib without the flag, the tests'
    fast-compile settings). The same arithmetic; the learning phase runs faster."""
    return dict(LEARNER_COMPILER_OPTIONS) if _chose_elemental else None


def knows_fast_cpu_compile() -> bool:
    """Whether the installed jaxlib's XLA takes :data:`FAST_CPU_COMPILE`: XLA aborts the
    process at start-up on a flag it does not know, and jaxlib 0.11 (seen with 0.11.2 on a GPU
    machine) no longer has this one; 0.10 has it (measured there)."""
    from jaxlib import version

    major_minor = tuple(int(part) for part in version.__version__.split(".")[:2])
    return major_minor == (0, 10)


def default_cache_dir() -> Path:
    """Where the commands keep compiled programs (see the module docstring)."""
    if os.environ.get(ENV_DIR):
        return Path(os.environ[ENV_DIR]).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base).expanduser() / "sgjax" / "jax"


def enable_compilation_cache(path: str | Path | None = None) -> Path | None:
    """Turn on JAX's persistent compilation cache in ``path`` (default
    :func:`default_cache_dir`) for this process. Returns the folder in use, or None when
    ``SGJAX_NO_COMPILATION_CACHE=1`` turns it off. A folder JAX was already given wins."""
    if os.environ.get(ENV_OFF) == "1":
        disable_compilation_cache()
        return None
    configured = jax.config.jax_compilation_cache_dir
    if configured:
        return Path(configured)
    folder = Path(path).expanduser() if path is not None else default_cache_dir()
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise OSError(f"compilation cache: cannot create {folder} ({err}); pass "
                      "--no-compilation-cache or set SGJAX_COMPILATION_CACHE to a writable "
                      "folder") from err
    jax.config.update("jax_compilation_cache_dir", str(folder))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)
    return folder


def add_cache_arguments(parser: argparse.ArgumentParser) -> None:
    """``--no-compilation-cache`` and ``--compilation-cache DIR`` on a command."""
    parser.add_argument("--no-compilation-cache", action="store_true",
                        help="compile everything afresh, without reading or writing JAX's "
                             "persistent compilation cache")
    parser.add_argument("--compilation-cache", metavar="DIR", default=None,
                        help=f"the cache folder (default: ${ENV_DIR} or "
                             "$XDG_CACHE_HOME/sgjax/jax, ~/.cache/sgjax/jax)")


def disable_compilation_cache() -> None:
    """No persistent cache for this process, even one configured for JAX elsewhere."""
    jax.config.update("jax_enable_compilation_cache", False)


def cache_from_arguments(args: argparse.Namespace) -> Path | None:
    """Apply a command's cache arguments (see :func:`add_cache_arguments`) and
    :func:`fast_cpu_compile`; returns the cache folder in use, or None."""
    fast_cpu_compile()
    if args.no_compilation_cache:
        disable_compilation_cache()
        return None
    return enable_compilation_cache(args.compilation_cache)
