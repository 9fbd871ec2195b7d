"""Build the worked-example notebooks from their plain-Python sources and execute them (no Jupyter needed).

Each notebook is written as a Python file in ``notebooks/src/`` in the "percent" cell format:

    # %% [markdown]
    # # A title
    # Some text (every line starts with "# ").

    # %%
    x = 1 + 1
    x                      # like Jupyter, a final expression is displayed

This builder turns every source into ``notebooks/<name>.ipynb`` (nbformat 4.5 JSON, written with ``json`` only) and,
unless ``--no-execute``, runs the code cells top to bottom in one namespace, storing what a kernel would show: text
printed to stdout/stderr, the value of a cell's final expression (its ``repr``, or a PNG for a matplotlib figure or
any object with ``_repr_png_``) and every matplotlib figure left open at the end of a cell. The cells run in a
scratch directory, so files the notebooks write do not land in the repository. A cell that raises stops the build
and no notebook is written.

    PYTHONPATH=$PWD python scripts/build_notebooks.py                  # every notebook
    PYTHONPATH=$PWD python scripts/build_notebooks.py 02_agents_and_regret
"""

from __future__ import annotations

import argparse
import ast
import base64
import contextlib
import io
import json
import os
import sys
import tempfile
import time
import traceback
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
SRC_DIR = ROOT / "notebooks" / "src"
OUT_DIR = ROOT / "notebooks"

_CELL_MARK = "# %%"
_MARKDOWN_MARK = "# %% [markdown]"


def parse_cells(text: str) -> list[tuple[str, str]]:
    """``(kind, source)`` pairs, ``kind`` being ``"code"`` or ``"markdown"``, of a percent-format source.

    Text before the first marker is ignored (a module docstring for the source file itself). Markdown lines lose
    their leading ``"# "`` (or a lone ``"#"``); leading and trailing blank lines of every cell are dropped.
    """
    cells: list[tuple[str, list[str]]] = []
    for line in text.splitlines():
        stripped = line.rstrip()
        if stripped == _MARKDOWN_MARK:
            cells.append(("markdown", []))
        elif stripped == _CELL_MARK:
            cells.append(("code", []))
        elif cells:
            kind, lines = cells[-1]
            if kind == "markdown":
                if stripped and not stripped.startswith("#"):
                    raise ValueError(f"markdown line without '# ': {line!r}")
                line = stripped[2:] if stripped.startswith("# ") else stripped[1:]
            lines.append(line)
    out = []
    for kind, lines in cells:
        while lines and not lines[0].strip():
            lines.pop(0)
        while lines and not lines[-1].strip():
            lines.pop()
        if lines:
            out.append((kind, "\n".join(lines)))
    return out


def _source_lines(text: str) -> list[str]:
    """Text as the list of lines (newlines kept) that nbformat stores."""
    return text.splitlines(keepends=True)


def _png_of_figure(fig: Any) -> bytes:
    buf = io.BytesIO()
    # No "Software" metadata, so a rebuild with the same numbers gives the same bytes.
    fig.savefig(buf, format="png", dpi=100, bbox_inches="tight", metadata={"Software": None})
    return buf.getvalue()


def _b64(data: bytes) -> str:
    return base64.b64encode(data).decode("ascii")


def _rich(value: Any) -> dict[str, Any]:
    """The mime bundle a kernel would show for ``value``."""
    data: dict[str, Any] = {"text/plain": _source_lines(repr(value))}
    try:
        from matplotlib.figure import Figure
    except ImportError:  # pragma: no cover - matplotlib is a dependency
        Figure = ()  # type: ignore[assignment]
    if isinstance(value, Figure):
        import matplotlib.pyplot as plt

        data["image/png"] = _b64(_png_of_figure(value))
        plt.close(value)
    elif hasattr(value, "_repr_png_"):
        data["image/png"] = _b64(value._repr_png_())
    return data


def _open_figures() -> list[dict[str, Any]]:
    """Display data for every open matplotlib figure (then closed), as the inline backend does after a cell."""
    if "matplotlib.pyplot" not in sys.modules:
        return []
    import matplotlib.pyplot as plt

    out = []
    for num in plt.get_fignums():
        fig = plt.figure(num)
        out.append({"output_type": "display_data", "metadata": {},
                    "data": {"text/plain": [repr(fig)], "image/png": _b64(_png_of_figure(fig))}})
        plt.close(fig)
    return out


def run_cell(source: str, namespace: dict[str, Any], count: int) -> list[dict[str, Any]]:
    """Execute one code cell in ``namespace``; returns its outputs (raises what the cell raises)."""
    tree = ast.parse(source, filename=f"<cell {count}>")
    last = None
    if tree.body and isinstance(tree.body[-1], ast.Expr):
        last = ast.Expression(tree.body.pop().value)
    stdout, stderr = io.StringIO(), io.StringIO()
    value = None
    with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
        exec(compile(tree, f"<cell {count}>", "exec"), namespace)
        if last is not None:
            value = eval(compile(last, f"<cell {count}>", "eval"), namespace)
    outputs: list[dict[str, Any]] = []
    for name, buf in (("stdout", stdout), ("stderr", stderr)):
        if buf.getvalue():
            outputs.append({"output_type": "stream", "name": name, "text": _source_lines(buf.getvalue())})
    if value is not None:
        outputs.append({"output_type": "execute_result", "execution_count": count, "metadata": {},
                        "data": _rich(value)})
    outputs.extend(_open_figures())
    return outputs


def build(name: str, execute: bool = True) -> dict[str, Any]:
    """The notebook JSON of ``notebooks/src/<name>.py`` (executed unless ``execute`` is False)."""
    cells = parse_cells((SRC_DIR / f"{name}.py").read_text())
    namespace: dict[str, Any] = {"__name__": "__main__"}
    nb_cells = []
    count = 0
    cwd = os.getcwd()
    with tempfile.TemporaryDirectory(prefix=f"nb_{name}_") as scratch:
        os.chdir(scratch)
        try:
            for i, (kind, source) in enumerate(cells):
                cell: dict[str, Any] = {"cell_type": kind, "id": f"{name[:2]}-{i:02d}", "metadata": {},
                                        "source": _source_lines(source)}
                if kind == "code":
                    count += 1
                    outputs = []
                    if execute:
                        t0, c0 = time.perf_counter(), time.process_time()
                        try:
                            outputs = run_cell(source, namespace, count)
                        except Exception:
                            print(f"{name}: cell {count} raised:\n{source}\n", file=sys.stderr)
                            traceback.print_exc()
                            raise
                        print(f"  {name} cell {count}: {time.perf_counter() - t0:.1f} s "
                              f"({time.process_time() - c0:.1f} s CPU)", file=sys.stderr)
                    cell.update(execution_count=count if execute else None, outputs=outputs)
                nb_cells.append(cell)
        finally:
            os.chdir(cwd)
    return {
        "cells": nb_cells,
        "metadata": {
            "kernelspec": {"display_name": "Python 3", "language": "python", "name": "python3"},
            "language_info": {"name": "python", "version": f"{sys.version_info.major}.{sys.version_info.minor}"},
        },
        "nbformat": 4,
        "nbformat_minor": 5,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("names", nargs="*", help="notebook names (default: every source in notebooks/src)")
    parser.add_argument("--no-execute", action="store_true", help="write the notebooks without running them")
    args = parser.parse_args(argv)
    os.environ.setdefault("MPLBACKEND", "Agg")
    names = args.names or sorted(p.stem for p in SRC_DIR.glob("*.py"))
    for name in names:
        if not (SRC_DIR / f"{name}.py").exists():
            parser.error(f"no source notebooks/src/{name}.py")
    for name in names:
        t0 = time.perf_counter()
        nb = build(name, execute=not args.no_execute)
        path = OUT_DIR / f"{name}.ipynb"
        path.write_text(json.dumps(nb, indent=1, ensure_ascii=False) + "\n")
        print(f"wrote {path.relative_to(ROOT)} ({time.perf_counter() - t0:.1f} s)", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
