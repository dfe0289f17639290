"""The one place where rbenvs compiles generated Python.

Why generated code at all: on Python floats a loop over state components (``for a, b in
zip(y, k)``) costs more than the physics it drives, so the explicit Runge-Kutta steps are
written out component by component, per state dimension, from their Butcher tableaus
(:mod:`rbenvs.integrators.runge_kutta`); the single env's read-out function is one generated
function of the task's and system's pure parts instead of a method call per part; and numba
needs the batch loops of the compiled step spelled out per layout (:mod:`rbenvs.compiled`).

Every source passes through :func:`generate`, which

* gives it a unique pseudo-file name ``<rbenvs generated: LABEL #K>`` and registers its text
  in :mod:`linecache`, so tracebacks, ``inspect.getsource`` and debuggers show the generated
  lines;
* when the environment variable ``RBENVS_DUMP_GENERATED`` names a folder, writes the text
  there as ``K-LABEL.py`` (created if needed), to read what runs.

``exec`` appears in this module only (a test checks it).
"""

from __future__ import annotations

import itertools
import linecache
import os
import re
from pathlib import Path

__all__ = ["generate", "DUMP_VARIABLE"]

# a folder to write every generated source to (for reading; unset: nothing is written)
DUMP_VARIABLE = "RBENVS_DUMP_GENERATED"

_counter = itertools.count(1)


def generate(source: str, label: str, namespace: dict | None = None) -> dict:
    """Compile and run ``source`` (module-level definitions) in ``namespace``; returns the
    namespace with the definitions. ``label`` names the source in tracebacks and dumps."""
    k = next(_counter)
    filename = f"<rbenvs generated: {label} #{k}>"
    if not source.endswith("\n"):
        source += "\n"
    # mtime None: linecache.checkcache keeps the entry (there is no file to compare with)
    linecache.cache[filename] = (len(source), None, source.splitlines(keepends=True), filename)
    folder = os.environ.get(DUMP_VARIABLE)
    if folder:
        path = Path(folder)
        path.mkdir(parents=True, exist_ok=True)
        safe = re.sub(r"[^A-Za-z0-9_.=-]+", "_", label).strip("_")
        (path / f"{k:04d}-{safe}.py").write_text(f"# {filename}\n{source}")
    namespace = {} if namespace is None else namespace
    # the definitions' __module__: an importable module (numba imports it to rebuild a cached
    # kernel's environment, rbenvs.kernel_cache), this one, where every generated source is made
    namespace.setdefault("__name__", __name__)
    exec(compile(source, filename, "exec"), namespace)
    return namespace
