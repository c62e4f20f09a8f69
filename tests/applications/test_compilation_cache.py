"""The commands' persistent compilation cache: its folder, the switch that turns it off, and a
second process that compiles nothing the first compiled."""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from sgjax.compilation_cache import default_cache_dir

PROGRAM = """
import jax, jax.numpy as jnp
from sgjax.compilation_cache import enable_compilation_cache
folder = enable_compilation_cache()
print("folder", folder)
jax.jit(lambda x: jnp.sin(x) * 3 + jnp.cos(x))(jnp.arange(7.0)).block_until_ready()
"""


def run(env):
    clean = {k: v for k, v in os.environ.items() if not k.startswith(("JAX_", "SGJAX_"))}
    return subprocess.run([sys.executable, "-c", PROGRAM], env={**clean, **env},
                          capture_output=True, text=True, timeout=300, check=True).stdout


def test_default_folder_follows_xdg_and_the_override(monkeypatch, tmp_path):
    monkeypatch.delenv("SGJAX_COMPILATION_CACHE", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert default_cache_dir() == tmp_path / "sgjax" / "jax"
    monkeypatch.setenv("SGJAX_COMPILATION_CACHE", str(tmp_path / "mine"))
    assert default_cache_dir() == tmp_path / "mine"


def test_a_second_process_reads_what_the_first_wrote_and_off_means_off(tmp_path):
    folder = tmp_path / "cache"
    first = run({"SGJAX_COMPILATION_CACHE": str(folder)})
    assert f"folder {folder}" in first
    written = {p.name: p.stat().st_mtime_ns for p in folder.iterdir()}
    assert written, "nothing was written to the cache"
    run({"SGJAX_COMPILATION_CACHE": str(folder)})
    # nothing compiled again: JAX writes an entry only on a miss
    assert {p.name: p.stat().st_mtime_ns for p in folder.iterdir()} == written
    off = tmp_path / "off"
    assert "folder None" in run({"SGJAX_COMPILATION_CACHE": str(off),
                                 "SGJAX_NO_COMPILATION_CACHE": "1"})
    assert not Path(off).exists()


FLAGS = """
import json, os, jax
from sgjax.compilation_cache import fast_cpu_compile, learner_compiler_options
before = fast_cpu_compile()
jax.devices()  # backends start: too late to change the flags afterwards
options = learner_compiler_options()
# a program compiled with the options runs (XLA takes them as flag overrides)
value = float(jax.jit(lambda x: jax.numpy.tanh(x) @ x, compiler_options=options)(
    jax.numpy.ones((3, 3))).sum())
print(json.dumps([before, fast_cpu_compile(), options, os.environ.get("XLA_FLAGS", ""),
                  round(value, 4)]))
"""


@pytest.mark.slow
def test_commands_compile_with_the_elemental_emitters_unless_told_not_to():
    """The commands' programs compile with the elemental emitters, the trainer's update
    (learner_compiler_options) with XLA's default ones; a user's choice is left alone."""
    def flags(env):
        clean = {k: v for k, v in os.environ.items()
                 if not k.startswith(("JAX_", "SGJAX_")) and k != "XLA_FLAGS"}
        return json.loads(subprocess.run([sys.executable, "-c", FLAGS], env={**clean, **env},
                                         capture_output=True, text=True, timeout=300,
                                         check=True).stdout)

    value = round(float((np.tanh(np.ones((3, 3))) @ np.ones((3, 3))).sum()), 4)
    assert flags({}) == [True, True, {"xla_cpu_use_fusion_emitters": True},
                         "--xla_cpu_use_fusion_emitters=false", value]
    assert flags({"SGJAX_XLA_DEFAULT_EMITTERS": "1"}) == [False, False, None, "", value]
    mine = "--xla_cpu_use_fusion_emitters=true --xla_backend_optimization_level=2"
    assert flags({"XLA_FLAGS": mine}) == [False, False, None, mine, value]
    elemental = "--xla_cpu_use_fusion_emitters=false"  # the user's own (as the tests set it)
    assert flags({"XLA_FLAGS": elemental}) == [True, True, None, elemental, value]


def test_a_jaxlib_without_the_emitter_flag_never_gets_it(monkeypatch):
    """XLA aborts the process on a flag it does not know (jaxlib 0.11.2 on a GPU machine, on
    ``--xla_cpu_use_fusion_emitters``): only jaxlib 0.10 is given it."""
    from jaxlib import version

    from sgjax import compilation_cache

    monkeypatch.setattr(version, "__version__", "0.11.2")
    assert not compilation_cache.knows_fast_cpu_compile()
    monkeypatch.setattr(compilation_cache.jax._src.xla_bridge, "backends_are_initialized",
                        lambda: False)
    monkeypatch.setenv("XLA_FLAGS", "--xla_dump_to=/tmp/x")
    assert compilation_cache.fast_cpu_compile() is False
    assert os.environ["XLA_FLAGS"] == "--xla_dump_to=/tmp/x"
    monkeypatch.setattr(version, "__version__", "0.10.2")
    assert compilation_cache.knows_fast_cpu_compile()
