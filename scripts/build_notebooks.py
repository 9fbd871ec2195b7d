"""Build the worked-example notebooks from their sources in ``notebooks/src/`` and execute them (the builder is
``notebooks/build.py``; ``--help`` lists its options).

    PYTHONPATH=$PWD python scripts/build_notebooks.py                  # every notebook
    PYTHONPATH=$PWD python scripts/build_notebooks.py 02_agents_and_regret
"""

import runpy
import sys
from pathlib import Path

if __name__ == "__main__":
    builder = runpy.run_path(str(Path(__file__).resolve().parents[1] / "notebooks" / "build.py"))
    sys.exit(builder["main"]())
