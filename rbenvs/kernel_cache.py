"""Compiled kernels kept on disk, so that a new process loads what an earlier one compiled.

Why: numba compiles a kernel the first time a process calls it (seconds for a vector env's
step: ``rbenvs warmup`` prints each), and rbenvs' kernels are generated per layout
(:mod:`rbenvs.compiled`), so numba's own ``cache=True``, which finds a function by its source file,
cannot keep them. Every kernel rbenvs compiles goes through :func:`njit`, which gives the dispatcher
a cache of its own: numba's compile results (the object code and what it needs to be linked again),
one file per kernel and argument types, named by a key over everything that changes the machine
code.

The key:

* the *environment*, one folder each (:func:`environment`): the Python, numba, llvmlite and
  numpy versions, numba's optimisation level and bounds checking, the CPU (LLVM's name and
  feature string) and a hash of rbenvs' own source files (an edit of rbenvs starts a new folder:
  a kernel inlines the package's functions; the modules no kernel calls into,
  :data:`NOT_COMPILED`, are left out);
* the *kernel*, one file name each (:func:`fingerprint`): the function's bytecode and constants,
  and, followed through closures, defaults and the globals its code names, every function it
  calls (a generated step's own source, the vector field it closes over, the parameters frozen
  into it), and the compile options;
* the argument types and numba's target description (triple, CPU, features), as numba keys its
  own cache.

Compiled once: a process that misses takes the kernel file's lock (``<file>.lock``, an advisory
``flock``) before it compiles, and one that finds it held waits for the file instead of compiling
the same kernel beside it (test workers, spawned env workers, Ray tasks on one machine starting
together); the lock goes with the compile, whatever its outcome (or the process), and a wait
longer than ``LOCK_WAIT_S`` compiles anyway.

Safe by construction: a file is written under a temporary name and renamed into place (a
reader sees a whole file or none; several processes compiling one kernel write the same bytes);
each file carries a SHA-256 of its contents and its own key, and one that does not verify
(truncated, corrupted, another kernel's) is compiled again and overwritten, never loaded. A
folder that cannot be made or written (read-only, full) turns the cache off for the process
with one :class:`KernelCacheWarning`; the kernels are then compiled in memory as before.

Where: ``$RBENVS_CACHE_DIR`` if set, else the platform's cache folder (``$XDG_CACHE_HOME/rbenvs``
or ``~/.cache/rbenvs`` on Linux, ``~/Library/Caches/rbenvs`` on macOS,
``%LOCALAPPDATA%\\rbenvs\\Cache`` on Windows). ``RBENVS_CACHE_DIR=`` (empty) turns the disk cache
off. ``rbenvs cache info`` and
``rbenvs cache clear`` show and empty it; ``rbenvs warmup`` fills it ahead.
"""

from __future__ import annotations

import hashlib
import os
import pickle
import sys
import tempfile
import threading
import time
import types
import uuid
import warnings
from functools import cache
from pathlib import Path

__all__ = [
    "njit",
    "cache_root",
    "kernel_folder",
    "environment",
    "fingerprint",
    "stats",
    "kernels",
    "clear",
    "info",
    "KernelCacheWarning",
    "CACHE_VARIABLE",
]

# the cache's root folder; set to an empty string to compile in memory only
CACHE_VARIABLE = "RBENVS_CACHE_DIR"

_MAGIC = b"RBENVSK1"  # the file format's tag (a new format: a new tag, and old files are misses)
_SUFFIX = ".nbk"

_lock = threading.Lock()
# the compile locks this process holds, by kernel file (an open descriptor holds the flock)
_held: dict = {}
LOCK_WAIT_S = 300.0  # (a holder that neither finishes nor exits: compile anyway after this)
_stats = {"loaded": 0, "compiled": 0, "rejected": 0, "saved": 0}
# (label, argument types, "loaded" or "compiled", seconds) of this process's kernels
_log: list = []
_off_reason: list = []  # why the disk cache is off in this process (the warning given once)


class KernelCacheWarning(RuntimeWarning):
    """The kernel cache cannot be used (its folder read-only or full): kernels are compiled in
    memory for the rest of the process."""


def cache_root() -> Path | None:
    """The cache's root folder (``None``: turned off by an empty ``$RBENVS_CACHE_DIR``)."""
    given = os.environ.get(CACHE_VARIABLE)
    if given is not None:
        return Path(given).expanduser() if given.strip() else None
    if sys.platform == "win32":
        base = os.environ.get("LOCALAPPDATA") or str(Path.home() / "AppData" / "Local")
        return Path(base) / "rbenvs" / "Cache"
    if sys.platform == "darwin":
        return Path.home() / "Library" / "Caches" / "rbenvs"
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "rbenvs"


# rbenvs' modules that no kernel calls into (no jitable function, no generated or compiled code:
# tests/test_kernel_cache.py checks it): left out of the source hash, so that an edit of the
# command line, the benches, verify or the renderers keeps the compiled kernels
NOT_COMPILED = (
    "bench",
    "verify",
    "render",
    "controllers",
    "oracles",
    "__main__.py",
    "cli.py",
    "docblocks.py",
    "extras.py",
    "headline.py",
    "plotting.py",
    "progress.py",
    "scenes.py",
    "testing.py",
)


@cache
def _source_hash() -> str:
    """SHA-256 over rbenvs' own source files (paths and contents), the package as installed,
    but the modules :data:`NOT_COMPILED`."""
    return _hash_sources(Path(__file__).resolve().parent)


def _hash_sources(package: Path) -> str:
    h = hashlib.sha256()
    for path in sorted(package.rglob("*.py")):
        if path.relative_to(package).parts[0] in NOT_COMPILED:
            continue
        h.update(str(path.relative_to(package)).encode())
        h.update(b"\0")
        h.update(path.read_bytes())
        h.update(b"\0")
    return h.hexdigest()


@cache
def environment() -> dict:
    """What the compiled machine code depends on besides the kernel itself: versions, CPU and
    rbenvs' source (a hash). Its :func:`_environment_key` names the folder of this process's
    kernels."""
    import llvmlite
    import llvmlite.binding as llvm
    import numba
    import numpy

    from . import __version__

    return {
        "rbenvs": __version__,
        "rbenvs_source": _source_hash()[:16],
        "python": (
            f"{sys.implementation.name}-{sys.version_info[0]}.{sys.version_info[1]}."
            f"{sys.version_info[2]}"
        ),
        "numba": numba.__version__,
        # numba's process-wide settings that change the code it emits
        "numba_settings": (int(numba.config.OPT), bool(numba.config.BOUNDSCHECK)),
        "llvmlite": llvmlite.__version__,
        "numpy": numpy.__version__,
        "cpu": llvm.get_host_cpu_name(),
        "cpu_features": hashlib.sha256(llvm.get_host_cpu_features().flatten().encode()).hexdigest()[
            :12
        ],
    }


def _environment_key() -> str:
    e = environment()
    # readable where it helps `rbenvs cache info`, hashed where it is long
    rest = hashlib.sha256(repr(sorted(e.items())).encode()).hexdigest()[:12]
    return f"{e['python']}-numba{e['numba']}-{e['cpu']}-{rest}"


def kernel_folder() -> Path | None:
    """This process's kernel folder (``None`` when the disk cache is off)."""
    root = cache_root()
    return None if root is None else root / "kernels" / _environment_key()


# --- the kernel's fingerprint --------------------------------------------------------------------


def _code_names(code: types.CodeType, out: set) -> set:
    out.update(code.co_names)
    for const in code.co_consts:
        if isinstance(const, types.CodeType):
            _code_names(const, out)
    return out


def _code_bytes(code: types.CodeType, h) -> None:
    h.update(code.co_code)
    h.update(repr(code.co_names).encode())
    h.update(repr(code.co_varnames).encode())
    h.update(repr(code.co_freevars).encode())
    for const in code.co_consts:
        if isinstance(const, types.CodeType):
            _code_bytes(const, h)
        else:
            h.update(_value_repr(const).encode())


def _value_repr(value) -> str:
    """An exact text for the plain values numba freezes into code (floats by their bits)."""
    if isinstance(value, float):
        return f"float:{value.hex()}"
    if isinstance(value, tuple):
        return "tuple(" + ",".join(_value_repr(v) for v in value) + ")"
    if value is None or isinstance(value, (bool, int, str, bytes, complex)):
        return f"{type(value).__name__}:{value!r}"
    return f"{type(value).__module__}.{type(value).__qualname__}"


def fingerprint(fn) -> str:
    """A SHA-256 over what a compiled ``fn`` depends on (the module docstring's "kernel")."""
    h = hashlib.sha256()
    _feed(fn, h, {})
    return h.hexdigest()


def _feed(obj, h, seen: dict) -> None:
    key = id(obj)
    if key in seen:  # (recursion, or a function reached twice: its position is enough)
        h.update(f"<seen {seen[key]}>".encode())
        return
    py_func = getattr(obj, "py_func", None)  # a numba dispatcher: its Python function
    if py_func is not None and callable(obj) and not isinstance(obj, types.FunctionType):
        h.update(b"dispatcher:")
        obj = py_func
        key = id(obj)
        if key in seen:
            h.update(f"<seen {seen[key]}>".encode())
            return
    seen[key] = len(seen)
    if isinstance(obj, types.FunctionType):
        _feed_function(obj, h, seen)
        return
    if isinstance(obj, types.ModuleType):
        h.update(f"module:{obj.__name__};".encode())
        return
    if isinstance(obj, (types.BuiltinFunctionType, type)):
        h.update(
            (
                f"{type(obj).__name__}:{getattr(obj, '__module__', '')}."
                f"{getattr(obj, '__qualname__', obj)};"
            ).encode()
        )
        return
    if isinstance(obj, tuple):
        h.update(f"tuple[{len(obj)}](".encode())
        for item in obj:
            _feed(item, h, seen)
        h.update(b")")
        return
    _feed_value(obj, h)


def _feed_function(fn, h, seen: dict) -> None:
    """A function: its code, defaults, closure, the globals its code names, and its declared
    compiled and scalar forms (what a kernel that calls it inlines)."""
    h.update(f"function:{fn.__module__}.{fn.__qualname__}:".encode())
    _code_bytes(fn.__code__, h)
    for value in fn.__defaults__ or ():
        _feed(value, h, seen)
    for cell in fn.__closure__ or ():
        try:
            content = cell.cell_contents
        except ValueError:  # an empty cell
            h.update(b"<empty cell>")
            continue
        _feed(content, h, seen)
    for name in sorted(_code_names(fn.__code__, set())):
        if name in fn.__globals__:
            h.update(f"global {name}=".encode())
            _feed(fn.__globals__[name], h, seen)
    form = getattr(fn, "__compiled_form__", None)  # (rbenvs.jit.compiled_form)
    if form is not None:
        h.update(b"compiled form:")
        _feed(form, h, seen)
    scalar = getattr(fn, "__scalar_form__", None)  # (rbenvs.jit.scalar_form)
    if scalar is not None:
        h.update(b"scalar form:")
        _feed(scalar, h, seen)


def _feed_value(obj, h) -> None:
    """A leaf: an array or numpy scalar by its bytes, a callable or enum member by its name, a
    plain value by its text, anything else by its type."""
    try:
        import numpy as np
    except ImportError:  # pragma: no cover - numba needs numpy
        np = None
    if np is not None and isinstance(obj, np.ndarray):
        h.update(f"ndarray:{obj.dtype.str}:{obj.shape}:".encode())
        h.update(np.ascontiguousarray(obj).tobytes())
        return
    if np is not None and isinstance(obj, np.generic):
        h.update(f"{type(obj).__name__}:{obj.tobytes().hex()};".encode())
        return
    if callable(obj) and hasattr(obj, "__qualname__"):  # numpy ufuncs and the like
        h.update(f"callable:{getattr(obj, '__module__', '')}.{obj.__qualname__};".encode())
        return
    import enum

    if isinstance(obj, enum.Enum):
        h.update(f"enum:{type(obj).__module__}.{type(obj).__qualname__}.{obj.name};".encode())
        return
    # plain values by their exact text; any other object (a list, a set, a dict, an instance) by
    # its type alone: numba freezes none of them into compiled code (a kernel that named one would
    # not compile), so they are reached only through Python-side names (a registry's list that
    # grows as modules are imported), and their contents or repr differ from process to process
    h.update(_value_repr(obj).encode() + b";")


# --- the cache numba's dispatcher calls ----------------------------------------------------------


def _turn_off(reason: str) -> None:
    with _lock:
        if _off_reason:
            return
        _off_reason.append(reason)
    warnings.warn(
        f"rbenvs' kernel cache is off for this process ({reason}); kernels are compiled in memory. "
        f"Set {CACHE_VARIABLE} to a writable folder, or to an empty string to silence this.",
        KernelCacheWarning,
        stacklevel=3,
    )


def _safe(label: str) -> str:
    return "".join(c if c.isalnum() or c in "-_=" else "_" for c in label).strip("_")[:60]


_probed: dict = {}  # folder -> whether this process could write there (probed once)


def _usable(folder: Path | None) -> bool:
    """Whether kernels can be kept in ``folder`` (made and probed with a file once per process;
    a folder that cannot be written turns the cache off with the warning)."""
    if folder is None or _off_reason:
        return False
    if folder not in _probed:
        try:
            folder.mkdir(parents=True, exist_ok=True)
            tempfile.NamedTemporaryFile(dir=folder, prefix=".probe-", delete=True).close()
            _probed[folder] = True
        except OSError as error:
            _probed[folder] = False
            _turn_off(f"cannot write {folder}: {error.strerror or error}")
    return _probed[folder] and not _off_reason


class _DiskCache:
    """What numba's dispatcher asks of a cache (``load_overload``, ``save_overload``,
    ``cache_path``, ``flush``), over one file per argument types in the kernel folder; with the
    cache off (no folder, or one that cannot be written) it only counts the compilations."""

    def __init__(self, py_func, label: str, options: dict):
        self._py_func = py_func
        self._label = _safe(label)
        self._options = repr(sorted(options.items()))
        self._folder = kernel_folder()
        self._kernel_key = None  # (computed on first use: the fingerprint walks the functions)

    @property
    def cache_path(self) -> str:
        return str(self._folder)

    def flush(self) -> None:  # (numba's Dispatcher.flush: forget what is saved)
        if self._folder is not None and self._kernel_key is not None:
            for path in self._folder.glob(f"{self._label}-{self._kernel_key[:24]}-*{_SUFFIX}"):
                try:
                    path.unlink()
                except OSError:
                    pass

    def _key(self, sig, codegen) -> tuple[str, Path]:
        if self._kernel_key is None:
            self._kernel_key = hashlib.sha256(
                (fingerprint(self._py_func) + self._options).encode()
            ).hexdigest()
        text = repr((self._kernel_key, str(sig), codegen.magic_tuple()))
        digest = hashlib.sha256(text.encode()).hexdigest()
        return text, self._folder / f"{self._label}-{self._kernel_key[:24]}-{digest[:16]}{_SUFFIX}"

    def load_overload(self, sig, target_context):
        self._started = (
            time.perf_counter()
        )  # (a miss: numba compiles next, then calls save_overload)
        if not _usable(self._folder):
            return None
        target_context.refresh()  # (numba's registries: a rebuilt kernel links against them)
        text, path = self._key(sig, target_context.codegen())
        cres, rejected = self._read(text, path, target_context)
        if cres is None:  # (once the lock is held, another process may have written it: again)
            _lock_compile(path)
            cres, again = self._read(text, path, target_context)
            rejected = again if cres is None else False
            if cres is not None:
                _unlock_compile(path)
        with _lock:
            if cres is not None:
                _stats["loaded"] += 1
                _log.append((self._label, len(sig), "loaded", time.perf_counter() - self._started))
            elif rejected:
                _stats["rejected"] += 1
        return cres

    def _read(self, text: str, path: Path, target_context) -> tuple:
        """``(compile result, rejected)``: the result in ``path`` where it is a whole file of this
        kernel; ``(None, True)`` for a file that does not verify; ``(None, False)``: no file."""
        from numba.core.compiler import CompileResult

        try:
            blob = path.read_bytes()
        except OSError:
            return None, False
        try:
            if blob[: len(_MAGIC)] != _MAGIC:
                raise ValueError("not a kernel file")
            digest, payload = blob[len(_MAGIC) : len(_MAGIC) + 32], blob[len(_MAGIC) + 32 :]
            if hashlib.sha256(payload).digest() != digest:
                raise ValueError("checksum")
            stored, data = pickle.loads(payload)
            if stored != text:
                raise ValueError("another kernel's file")
            return CompileResult._rebuild(target_context, *data), False
        except Exception:  # a file that does not verify is compiled again (and overwritten)
            return None, True

    def save_overload(self, sig, cres) -> None:
        with _lock:
            _stats["compiled"] += 1
            _log.append(
                (
                    self._label,
                    len(sig),
                    "compiled",
                    time.perf_counter() - getattr(self, "_started", time.perf_counter()),
                )
            )
        if not _usable(self._folder):
            return
        if any(not x.can_cache for x in cres.lifted) or cres.library.has_dynamic_globals:
            return  # (numba's rule: object-mode lifts and frozen large arrays cannot be reloaded)
        from numba.core.serialize import dumps

        text, path = self._key(sig, cres.codegen)
        payload = dumps((text, cres._reduce()))  # (numba's pickler: what its own cache writes)
        blob = _MAGIC + hashlib.sha256(payload).digest() + payload
        tmp = path.with_name(f"{path.name}.tmp.{uuid.uuid4().hex[:12]}")
        try:
            with open(tmp, "wb") as f:
                f.write(blob)
            os.replace(tmp, path)  # atomic: a reader sees the old file, the new one, or none
        except OSError as error:
            try:
                tmp.unlink()
            except OSError:
                pass
            _turn_off(f"cannot write {self._folder}: {error.strerror or error}")
            return
        with _lock:
            _stats["saved"] += 1
        _unlock_compile(path)


def _lock_compile(path: Path) -> None:
    """Hold the compile lock of the kernel file ``path`` (missing: this process is about to
    compile it), waiting while another process holds it. Without ``flock`` (Windows), where the
    lock file cannot be opened, or after ``LOCK_WAIT_S``: no lock."""
    try:
        import fcntl
    except ImportError:
        return
    if path in _held:
        return
    try:
        fd = os.open(path.with_name(path.name + ".lock"), os.O_RDWR | os.O_CREAT, 0o644)
    except OSError:
        return
    deadline = time.monotonic() + LOCK_WAIT_S
    while True:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            _held[path] = fd
            return
        except BlockingIOError:
            if time.monotonic() > deadline:
                break
            time.sleep(0.02)
        except OSError:
            break
    os.close(fd)


def _unlock_compile(path) -> None:
    """Let go of the compile lock of the kernel file ``path`` (if this process holds it)."""
    fd = _held.pop(path, None)
    if fd is not None:
        os.close(fd)  # (closing the descriptor releases the flock)


def njit(fn, label: str, **options):
    """``numba.njit(**options)(fn)`` whose compile results are kept in the kernel folder and
    loaded from there by later processes (``label`` names the files, for reading)."""
    import numba

    dispatcher = numba.njit(**options)(fn)
    dispatcher._cache = _DiskCache(
        fn, label, options
    )  # (the attribute numba's enable_caching sets)
    compile_ = dispatcher.compile

    def compile(sig):  # (whatever the compile's outcome, the locks it took are let go)
        before = set(_held)
        try:
            return compile_(sig)
        finally:
            for path in set(_held) - before:
                _unlock_compile(path)

    dispatcher.compile = compile
    return dispatcher


def kernels() -> list[tuple]:
    """This process's kernels in the order they were first called: ``(label, number of
    arguments, "loaded" or "compiled", seconds)`` (``rbenvs warmup`` prints them)."""
    with _lock:
        return list(_log)


def stats() -> dict:
    """This process's counts: kernels ``loaded`` from disk, ``compiled`` (each a miss),
    ``saved``, and files ``rejected`` (did not verify)."""
    with _lock:
        return dict(_stats)


def info() -> dict:
    """The cache's root, this process's folder and every environment folder with its files and
    bytes (``rbenvs cache info``)."""
    root = cache_root()
    out = {"root": None if root is None else str(root), "current": None, "folders": []}
    if root is None:
        return out
    try:
        out["current"] = _environment_key()
    except ImportError:  # numba not installed: nothing is compiled, the folders can still be listed
        pass
    kernels = root / "kernels"
    if kernels.is_dir():
        for folder in sorted(p for p in kernels.iterdir() if p.is_dir()):
            files = [p for p in folder.iterdir() if p.is_file() and p.suffix == _SUFFIX]
            out["folders"].append(
                {
                    "name": folder.name,
                    "files": len(files),
                    "bytes": sum(p.stat().st_size for p in files),
                }
            )
    return out


def clear(stale_only: bool = False) -> int:
    """Delete the kernel files (every environment's, or with ``stale_only`` all but this
    process's); returns how many files were deleted."""
    import shutil

    root = cache_root()
    if root is None or not (root / "kernels").is_dir():
        return 0
    keep = _environment_key() if stale_only else None
    count = 0
    for folder in (root / "kernels").iterdir():
        if folder.name == keep or not folder.is_dir():
            continue
        count += sum(1 for p in folder.iterdir() if p.suffix == _SUFFIX)
        shutil.rmtree(folder, ignore_errors=True)
    return count
