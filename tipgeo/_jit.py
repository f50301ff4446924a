"""numba's ``njit`` for tipgeo's compiled kernels, with cached kernels loaded
without numba's full target refresh.

numba refreshes its CPU target before loading a kernel from its on-disk
cache: it imports every lowering registry it has (numpy's linear algebra,
random generators, typed containers, …; about 0.3 CPU s, a sixth of a whole
``tipgeo compare`` at 10⁶ points), which only compiling needs — the loaded
machine code links against numba's runtime alone. :func:`njit` here loads
cached kernels after initialising that runtime only; a kernel not in the
cache is compiled as usual (numba's compiler refreshes the target itself
before it compiles). The change is made once, to numba's cache loader, when
this module is first imported, and only when that loader has the form this
was written against (numba ≥ 0.57); otherwise numba is left as it is.

A cached kernel carries the environments of numba's own helper functions
it inlined (array allocation, slicing, sorting), each naming its module;
numba imports that module to rebuild the environment — ``numba.np.arrayobj``
pulls in numba's unicode and hashing implementations, 25–35 ms of a
compare. The lean loader rebuilds those of numba's modules not yet imported
on a stand-in globals dictionary holding only the module's name: only
object-mode code reads an environment's globals, and nopython helpers have
none (their constants, which they do read, are restored as numba does).

When tipgeo runs as a program (the ``tipgeo`` command), numba's scan of
every installed distribution for third-party numba extensions is marked
done before the first kernel call (:func:`skip_extension_scan`): tipgeo's
kernels take numpy arrays and numbers only, and the scan cost 20–27 ms of a
compare. A library user's process is left as it is.

No units: a pass-through of numba's decorator.
"""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Iterator
from typing import Any

from numba import njit

__all__ = ["njit", "cache_loads_lean", "skip_extension_scan"]


def _lean_cache_loads() -> bool:
    """Replace numba's ``Cache.load_overload`` by one that initialises the
    runtime and loads, without the registry refresh; False when numba's
    cache loader is not of the expected form (then nothing is changed)."""
    try:
        from numba.core.caching import Cache
        from numba.core.runtime.nrt import rtsys
    except ImportError:  # pragma: no cover - another numba layout
        return False
    current = Cache.load_overload
    if getattr(current, "_tipgeo_lean", False):
        return True
    if not (hasattr(Cache, "_load_overload") and hasattr(Cache, "_guard_against_spurious_io_errors")
            and hasattr(rtsys, "initialize")):
        return False  # pragma: no cover - another numba layout

    def load_overload(self: Any, sig: Any, target_context: Any) -> Any:
        # the runtime (NRT) the loaded code calls into; the lowering
        # registries are loaded by the compiler if a kernel must be compiled
        rtsys.initialize(target_context)
        try:
            with self._guard_against_spurious_io_errors(), _stand_in_environments():
                return self._load_overload(sig, target_context)
        except Exception:  # e.g. a symbol only a registry provides: numba's own way
            return current(self, sig, target_context)  # type: ignore[no-untyped-call]

    load_overload._tipgeo_lean = True  # type: ignore[attr-defined]
    Cache.load_overload = load_overload  # type: ignore[method-assign]  # see the module docstring
    return True


@contextlib.contextmanager
def _stand_in_environments() -> Iterator[None]:
    """While a cached kernel is unpickled (numba's global compiler lock
    held: ``Dispatcher.compile`` takes it), the environments of numba's own
    modules not yet imported are rebuilt on a stand-in globals dictionary
    (see the module docstring); every other one as numba does. Nothing
    changes when numba's environment module is not of the expected form."""
    try:
        from numba.core import environment
    except ImportError:  # pragma: no cover - another numba layout
        yield
        return
    rebuild = getattr(environment, "_rebuild_env", None)
    Environment = getattr(environment, "Environment", None)
    if rebuild is None or Environment is None or not hasattr(Environment, "_memo") \
            or not hasattr(environment, "lookup_environment"):
        yield  # pragma: no cover - another numba layout
        return

    def stand_in(modname: Any, consts: Any, env_name: Any) -> Any:
        if not (isinstance(modname, str) and modname.startswith("numba.")
                and modname not in sys.modules):
            return rebuild(modname, consts, env_name)
        env = environment.lookup_environment(env_name)  # type: ignore[no-untyped-call]
        if env is not None:
            return env
        env = Environment({"__name__": modname})
        env.consts[:] = consts
        env.env_name = env_name
        Environment._memo[env_name] = env
        return env

    environment._rebuild_env = stand_in
    try:
        yield
    finally:
        environment._rebuild_env = rebuild


#: whether numba's cache loader was made lean (False: numba as it is)
cache_loads_lean: bool = _lean_cache_loads()


def skip_extension_scan() -> bool:
    """In the tipgeo program only, mark numba's extension entry points as
    initialised (see the module docstring); whether it was done."""
    from ._threads import is_program

    if not is_program():
        return False
    try:
        from numba.core import entrypoints
    except ImportError:  # pragma: no cover - another numba layout
        return False
    if not hasattr(entrypoints, "_already_initialized"):
        return False  # pragma: no cover - another numba layout
    entrypoints._already_initialized = True
    return True


#: whether numba's extension scan was skipped (the tipgeo program)
extension_scan_skipped: bool = skip_extension_scan()
