"""Where numba caches the compiled filter kernels, and whether a run must compile them first.

The kernels (:mod:`obsplan.estimation.kernels`, :mod:`~obsplan.estimation.montecarlo.loop_kernels`)
are compiled on first use and cached on disk (``cache=True``); a cold compile takes about a minute
on a small machine, which the first Monte Carlo would otherwise spend on an unlabelled progress
bar. :func:`configure` points numba's cache at a per-user cache folder when the user has not
chosen one (``NUMBA_CACHE_DIR``), so that the cache is written even when the package sits in a
read-only ``site-packages``, and is shared by every process of the user (Dask workers included);
:func:`compile_note` is the progress bar's label while the kernels compile.

That folder is named by :func:`kernel_fingerprint`, a hash of the estimation modules' sources.
numba's cache checks only the time stamp of the file a kernel is defined in, but a compiled kernel
also holds what it inlined from other files: the kernels it calls (``loop_kernels`` calls
``kernels``) and module constants (the channel's, the column layout). A cache written before such
a file changed would be loaded unchanged and run stale code against new callers — after an
upgrade, or an edit of a source checkout. A fingerprint of every source that kernels can reach
sends each version of them to its own folder.
"""

from __future__ import annotations

import hashlib
import os
import sys
from pathlib import Path

#: Seconds a cold compile of the kernels takes, as said in the progress label (measured: 55 s
#: on 2 cores idle, 94 s with the cores shared by four other jobs).
COMPILE_S = 60
#: The modules holding cached kernels (names under ``obsplan.estimation``): every Monte Carlo
#: uses the first, the closed loop both.
KERNEL_SOURCES = ("kernels", "montecarlo.loop_kernels")
HERE = Path(__file__).resolve().parent
#: The label of a Monte Carlo's progress bar while the kernels compile.
COMPILE_NOTE = f"compiling the filters once (about {COMPILE_S} s; cached for later runs)"


def user_cache_dir() -> Path:
    """The per-user folder for obsplan's numba cache (``~/.cache/obsplan/numba`` on Linux, or
    under ``XDG_CACHE_HOME``; ``~/Library/Caches`` on macOS, ``%LOCALAPPDATA%`` on Windows).

    Returns
    -------
    Path
        The folder (not created here).
    """
    if sys.platform == "win32":
        base = os.environ.get("LOCALAPPDATA") or str(Path.home() / "AppData" / "Local")
    elif sys.platform == "darwin":
        base = str(Path.home() / "Library" / "Caches")
    else:
        base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "obsplan" / "numba"


def kernel_fingerprint() -> str:
    """A hash of every source the kernels can inline: the modules of ``obsplan.estimation`` and
    of its ``montecarlo`` room (module docstring: why numba's own check is not enough).

    Returns
    -------
    str
        16 hexadecimal digits; changes when any of those files changes.
    """
    digest = hashlib.sha256()
    for path in sorted([*HERE.glob("*.py"), *(HERE / "montecarlo").glob("*.py")]):
        digest.update(path.relative_to(HERE).as_posix().encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def configure() -> Path | None:
    """Set ``NUMBA_CACHE_DIR`` to :func:`user_cache_dir` ``/`` :func:`kernel_fingerprint` unless it
    is set already; returns the cache folder in use, or None when no user folder can be written
    (numba then keeps its own choice: beside the sources, or its user-wide fallback).

    Returns
    -------
    Path or None
        ``NUMBA_CACHE_DIR`` if it was set, else the user folder now set; None if it cannot be
        written.
    """
    chosen = os.environ.get("NUMBA_CACHE_DIR")
    if chosen:
        return Path(chosen)
    folder = user_cache_dir() / kernel_fingerprint()
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError:  # a read-only home (some containers): leave numba's default
        return None
    if not os.access(folder, os.W_OK):
        return None
    os.environ["NUMBA_CACHE_DIR"] = str(folder)
    numba = sys.modules.get("numba")
    if numba is not None:  # read at import; numba's cache locator reads the config when compiling
        numba.config.CACHE_DIR = str(folder)
    return folder


def compiled_in_process(name: str) -> bool:
    """Whether this process has compiled (or loaded from the cache) any kernel of the module
    ``name`` (a module of :data:`KERNEL_SOURCES`).

    Parameters
    ----------
    name : str
        Module name under ``obsplan.estimation``, e.g. ``"kernels"``.

    Returns
    -------
    bool
        True if the module is imported and one of its kernels has a compiled signature.
    """
    module = sys.modules.get(f"obsplan.estimation.{name}")
    if module is None:
        return False
    return any(bool(getattr(f, "signatures", None)) for f in vars(module).values())


def cache_is_cold(sources: tuple[str, ...] = KERNEL_SOURCES, cache_dir: Path | None = None) -> bool:
    """Whether a kernel module of ``sources`` will be compiled on first use in this process:
    none of its kernels is compiled here yet, and the cache holds no index of it, or one older
    than its source (numba recompiles a function whose source changed).

    Parameters
    ----------
    sources : tuple of str, optional
        Modules of :data:`KERNEL_SOURCES` the run needs.
    cache_dir : Path or None, optional
        The cache folder (default: :func:`configure`'s; None there: numba's folder beside the
        sources).

    Returns
    -------
    bool
        True if some module of ``sources`` must be compiled.
    """
    cache_dir = cache_dir if cache_dir is not None else configure()
    for name in sources:
        if compiled_in_process(name):
            continue
        source = HERE / (name.replace(".", "/") + ".py")
        if cache_dir is None:
            folder = source.parent / "__pycache__"
        else:
            # numba's own naming of a source folder's cache (loaded with the kernels anyway)
            from numba.core.caching import UserProvidedCacheLocator

            folder = cache_dir / UserProvidedCacheLocator.get_suitable_cache_subpath(str(source))
        stamp = source.stat().st_mtime
        indexes = list(folder.glob(f"{source.stem}.*.nbi")) if folder.is_dir() else []
        if not indexes or min(p.stat().st_mtime for p in indexes) < stamp:
            return True
    return False


def compile_note(closed_loop: bool = True) -> str | None:
    """:data:`COMPILE_NOTE` when the kernels a Monte Carlo needs (the closed loop's too if
    ``closed_loop``) are about to be compiled (:func:`cache_is_cold`), else None.

    Parameters
    ----------
    closed_loop : bool, optional
        The run also needs the closed loop's kernels
        (:mod:`~obsplan.estimation.montecarlo.loop_kernels`).

    Returns
    -------
    str or None
        The progress bar's label, or None if nothing is compiled.
    """
    sources = KERNEL_SOURCES if closed_loop else KERNEL_SOURCES[:1]
    return COMPILE_NOTE if cache_is_cold(sources) else None
