"""What every console command shares: the ``--no-compile-cache`` flag and the closing compile-time line."""

from __future__ import annotations

import argparse
import contextlib
import sys
import time
from collections.abc import Iterator

from jaxmdp.experiment import compilation


def add_cache_flag(parser: argparse.ArgumentParser) -> None:
    """``--no-compile-cache`` (:func:`jaxmdp.experiment.compilation.add_cache_flag`)."""
    compilation.add_cache_flag(parser)


@contextlib.contextmanager
def compile_report(no_cache: bool) -> Iterator[None]:
    """Turn on the persistent compilation cache (unless ``no_cache``) and count compile time; when the block ends
    without an error, write the wall time and the part spent compiling to stderr. Enter it before anything compiles."""
    folder, stats = compilation.setup_compilation(no_cache)
    start = time.perf_counter()
    yield
    print(compilation.time_report(time.perf_counter() - start, stats.snapshot(), folder), file=sys.stderr)


def load_agent(spec: str) -> str:
    """The registry name of the agent ``spec`` names: a registered name as it is, or ``module:NAME`` /
    ``path/to/file.py:NAME``, whose module is imported (a dotted module is searched on ``sys.path`` with the current
    directory first, as ``python -m`` does; a file is loaded from its path, its folder put on ``sys.path`` for its own
    imports) and whose ``NAME`` must be an :class:`jaxmdp.agent_interface.Agent`, then registered
    (:func:`agents.register`; a module may register it itself, with its search space). ``ValueError`` otherwise."""
    import importlib
    import importlib.util
    import os
    from pathlib import Path

    import agents
    from jaxmdp._checks import did_you_mean
    from jaxmdp.experiment.agent_interface import Agent

    where, colon, attribute = spec.rpartition(":")
    if not colon:
        return spec
    if not where or not attribute.isidentifier():
        raise ValueError(f"agent {spec!r}: write module:NAME (my_agents:MY_AGENT) or path/to/file.py:NAME")
    try:
        if where.endswith(".py") or os.sep in where or "/" in where:
            path = Path(where).resolve()
            if not path.is_file():
                raise ValueError(f"agent {spec!r}: no file {path}")
            name = path.stem
            module = sys.modules.get(name)
            if module is None or Path(getattr(module, "__file__", "") or "").resolve() != path:
                loader_spec = importlib.util.spec_from_file_location(name, path)
                module = importlib.util.module_from_spec(loader_spec)
                if str(path.parent) not in sys.path:
                    sys.path.insert(0, str(path.parent))
                sys.modules[name] = module
                loader_spec.loader.exec_module(module)
        else:
            if os.getcwd() not in sys.path and "" not in sys.path:
                sys.path.insert(0, os.getcwd())
            module = importlib.import_module(where)
    except ModuleNotFoundError as err:
        raise ValueError(f"agent {spec!r}: cannot import {where!r} ({err}); run from the folder that holds it, put "
                         "that folder on PYTHONPATH, or give the file's path (path/to/file.py:NAME)") from None
    if not hasattr(module, attribute):
        known = [k for k, v in vars(module).items() if isinstance(v, Agent)]
        raise ValueError(f"agent {spec!r}: module {where!r} has no {attribute!r}{did_you_mean(attribute, known)} "
                         f"Agents it defines: {', '.join(known) or 'none'}")
    agent = getattr(module, attribute)
    if not isinstance(agent, Agent):
        raise ValueError(f"agent {spec!r}: {attribute} is a {type(agent).__name__}, not a "
                         "jaxmdp.agent_interface.Agent")
    agents.register(agent)
    return agent.name


def load_agents(specs: list[str] | None) -> list[str] | None:
    """:func:`load_agent` of every spec (``None`` stays ``None``)."""
    return None if specs is None else [load_agent(s) for s in specs]
